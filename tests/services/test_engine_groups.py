"""services.engine.networks: a stacked group built from the networks' own (in, out) layouts
(`LoadedNet.row_layers`, made once at load) holds exactly the arrays stacked from their
tensors, for every partition and layer, with the task network repeated."""

from __future__ import annotations

import dataclasses

import numpy as np

from model_store import task_model_name
from services.engine.networks import build_group, load_net


def test_groups_from_row_layers_equal_groups_from_tensors(tiny_zoo) -> None:
    store = tiny_zoo.store
    names = [
        task_model_name("particle", "a2"),
        *(f"particle/impact/{g}" for g in ("b3", "c1", "e0")),
    ]
    nets = [load_net(store, store.resolve(f"{name}@production")) for name in names]
    assert all(net.row_layers for net in nets)
    bare = [dataclasses.replace(net, row_layers=()) for net in nets]  # made without load_net
    for repeats in (1, 4):
        a, b = build_group(nets, repeats), build_group(bare, repeats)
        for part_a, part_b in zip(a.partitions, b.partitions, strict=True):
            assert part_a.first_repeats == part_b.first_repeats
            for (wa, ba), (wb, bb) in zip(part_a.row_weights, part_b.row_weights, strict=True):
                np.testing.assert_array_equal(wa, wb)
                np.testing.assert_array_equal(ba, bb)
                assert wa.flags.c_contiguous and wa.dtype == np.float32
            for (wa, ba), (wb, bb) in zip(part_a.weights, part_b.weights, strict=True):
                np.testing.assert_array_equal(wa, wb)
                np.testing.assert_array_equal(ba, bb)
            # the general path's (G, out, in) layout is the tensors' own
            first = part_a.members[0]
            np.testing.assert_array_equal(
                part_a.weights[0][0][0], nets[first].tensors["layers.0.weight"]
            )
