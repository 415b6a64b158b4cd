"""services.engine.networks: a stacked group built from the networks' own (in, out) layouts
(`LoadedNet.row_layers`, made once at load) holds exactly the arrays stacked from their
tensors, for every partition and layer."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

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
    a, b = build_group(nets), build_group(bare)
    for part_a, part_b in zip(a.partitions, b.partitions, strict=True):
        for (wa, ba), (wb, bb) in zip(part_a.row_weights, part_b.row_weights, strict=True):
            np.testing.assert_array_equal(wa, wb)
            np.testing.assert_array_equal(ba, bb)
            assert wa.flags.c_contiguous and wa.dtype == np.float32
        # the (in, out) layout is the tensors' own (out, in) transposed, member by member
        for g, j in enumerate(part_a.members):
            np.testing.assert_array_equal(
                part_a.row_weights[0][0][g].T, nets[j].tensors["layers.0.weight"]
            )


def test_a_belief_batch_that_overflows_is_a_clear_error(tiny_zoo) -> None:
    """A batch mixing goal distributions used to reach `mix_goal_beliefs`' checks with the
    overflowed Q-values and raise ValueError (a 500); it is the engine's InvalidRequest now."""
    from services.engine import ActRequest, InferenceEngine, InvalidRequest, PartnerSpec

    engine = InferenceEngine(tiny_zoo.store)
    partner = (PartnerSpec(1, goal_probs={"b3": 0.5, "c1": 0.5}),)
    with pytest.raises(InvalidRequest) as err:
        engine.act(ActRequest("particle", "a2", np.full((2, 8), 3e38), partner))
    assert err.value.field == "observations" and "overflow" in err.value.message


def test_general_path_layouts_are_remembered(tiny_zoo) -> None:
    """The same partners' goals give the same `ModelUsed` objects (the REST session route
    writes their JSON once per set) and the same numbers as before the memo."""
    from services.engine import ActRequest, InferenceEngine, PartnerSpec

    engine = InferenceEngine(tiny_zoo.store)
    obs = np.random.default_rng(5).random((3, 12))
    partners = (
        PartnerSpec(1, goal_probs={"b3": 0.25, "c1": 0.75}),
        PartnerSpec(2, goal_probs={"b3": 0.5, "c1": 0.5}),
    )
    first, second = (engine.act(ActRequest("particle", "a2", obs, partners)) for _ in range(2))
    assert all(a is b for a, b in zip(first[0].models, second[0].models, strict=True))
    assert [r.probs for r in first] == [r.probs for r in second]
    assert [m.partner_index for m in first[0].models] == [None, 1, 1, 2, 2]


@pytest.mark.parametrize("numpy_forward", [False, True])
@pytest.mark.parametrize("announced", [True, False])
@pytest.mark.parametrize("batch", [1, 3])
def test_goal_distributions_mix_as_mix_goal_beliefs_does(
    tiny_zoo, batch: int, announced: bool, numpy_forward: bool
) -> None:
    """`planning.impact_q` mixes equal-size distributions in one pass over the impact members'
    rows (`policy.belief_compiled.compiled_mix_goals`): each partner's expected Q is
    `mix_goal_beliefs` of its own goals' Q-values (with an announced partner and a distribution
    of another size beside them, or every partner a distribution over the same goals, as a
    session's beliefs), also on the Q-values of the numpy forward (an install without a C
    compiler)."""
    from policy.blend import mix_goal_beliefs
    from services.engine import ActRequest, InferenceEngine, PartnerSpec
    from services.engine.networks import forward_group
    from services.engine.planning import impact_q, layout_of, member_inputs, plan_members
    from services.engine.validation import check_request

    engine = InferenceEngine(tiny_zoo.store)
    rng = np.random.default_rng(batch)
    goals = ["b3", "c1"]

    def belief() -> dict[str, float]:
        return dict(zip(goals, rng.dirichlet([1, 1]).tolist(), strict=True))

    partners = (
        PartnerSpec(1, goal_probs=belief()),
        PartnerSpec(2, goal="c1") if announced else PartnerSpec(2, goal_probs=belief()),
        PartnerSpec(3, goal_probs=belief()),
        PartnerSpec(4, goal_probs={"b3": 1.0})
        if announced
        else PartnerSpec(4, goal_probs=belief()),
    )
    request = ActRequest("particle", "a2", rng.random((batch, 20)), partners)
    checked = check_request(request, 4096)
    members, needs = plan_members(request, checked)
    domain = checked.runtime.domain
    _, group = engine.cache.resolve_group(needs, "production", {}, members, domain)
    layout = layout_of(checked, members, group)
    inputs = member_inputs(checked, members, group, layout)
    q_members = forward_group(group, inputs, numpy_forward=numpy_forward)
    got = impact_q(checked, q_members, layout)
    assert got.shape == (batch, 4, 5) and got.flags.c_contiguous
    for position, partner in enumerate(checked.partners):
        blocks = [layout.slots[(position, goal)] for goal in partner.goals]
        q_BGA = np.stack([q_members[j][k * batch : (k + 1) * batch] for j, k in blocks], axis=1)
        if partner.probs is None:
            np.testing.assert_array_equal(got[:, position], q_BGA[:, 0])
            continue
        probs = np.broadcast_to(np.asarray(partner.probs), (batch, 1, len(blocks)))
        want = mix_goal_beliefs(q_BGA[:, None].astype(np.float64), probs)[:, 0]
        np.testing.assert_allclose(got[:, position], want, rtol=1e-12, atol=1e-12)


def test_member_rows_come_from_the_call_that_served_them(tiny_zoo) -> None:
    """`MemberQ.rows_from(j)`: the rows of members j.. one after the other; the output of the
    forward's call itself (no copy) when one call served exactly those members, else joined."""
    from services.engine.networks import forward_group

    store = tiny_zoo.store
    names = [
        task_model_name("particle", "a2"),
        *(f"particle/impact/{g}" for g in ("b3", "c1", "e0")),
    ]
    nets = [load_net(store, store.resolve(f"{name}@production")) for name in names]
    group = build_group(nets)
    rng = np.random.default_rng(0)
    task_rows, shared = (rng.standard_normal((4, 8)).astype(np.float32) for _ in range(2))
    together = forward_group(group, [task_rows, shared, shared, shared])
    joined = together.rows_from(1)
    np.testing.assert_array_equal(joined, np.concatenate(together[1:]))
    assert np.shares_memory(joined, together[1]) and np.shares_memory(joined, together[3])
    # members 1 and 2 on one input, member 3 on another: two calls, the rows joined by a copy
    apart = forward_group(group, [task_rows, shared, shared, shared[:2].copy()])
    np.testing.assert_array_equal(apart.rows_from(1), np.concatenate(apart[1:]))
    assert not np.shares_memory(apart.rows_from(1), apart[1])
    assert apart.rows_from(3).shape == (2, 5)


@pytest.mark.parametrize("rows", [1, 4, 7, 65])  # compiled (<= 8), stacked numpy, one by one
def test_members_sharing_an_input_equal_members_on_copies(tiny_zoo, rows: int) -> None:
    """`forward_group` gives members handed the very same input array that array once (a
    belief's impact networks); each member's Q-values are those of the same network on its
    own copy of the rows, and of the network evaluated alone."""
    from services.engine.networks import _runs, forward_group

    store = tiny_zoo.store
    names = [
        task_model_name("particle", "a2"),
        *(f"particle/impact/{g}" for g in ("b3", "c1", "e0")),
    ]
    nets = [load_net(store, store.resolve(f"{name}@production")) for name in names]
    group = build_group(nets)
    rng = np.random.default_rng(rows)
    task_rows = rng.standard_normal((rows, 8)).astype(np.float32)
    shared = rng.standard_normal((rows, 8)).astype(np.float32)
    inputs = [task_rows, shared, shared, shared]
    copies = [task_rows, *(shared.copy() for _ in range(3))]
    assert [run for part in group.partitions for run in _runs(part, inputs)] == [
        (0, 1, False),
        (1, 4, True),
    ]
    assert [run for part in group.partitions for run in _runs(part, copies)] == [(0, 4, False)]
    together, apart = forward_group(group, inputs), forward_group(group, copies)
    for j, net in enumerate(nets):
        alone = forward_group(build_group([net]), [inputs[j]])[0]
        np.testing.assert_allclose(together[j], apart[j], rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(together[j], alone, rtol=1e-5, atol=1e-5)


def test_member_q_values_of_non_consecutive_members_are_found_by_member(tiny_zoo) -> None:
    """A partition whose members are not consecutive in the group (two specs interleaved) is
    served by one call; `MemberQ[j]` still gives member j's own rows (from either kind of call,
    negative indices too), iteration stops at the last member and a member beyond it is an
    IndexError."""
    from services.engine.networks import forward_group

    store = tiny_zoo.store
    names = [
        task_model_name("particle", "a2"),
        *(f"particle/impact/{g}" for g in ("b3", "c1")),
    ]
    nets = [load_net(store, store.resolve(f"{name}@production")) for name in names]
    # the same weights under another activation: a second partition, member 1 alone
    nets[1] = dataclasses.replace(
        nets[1], spec=dataclasses.replace(nets[1].spec, activation="tanh")
    )
    group = build_group(nets)
    assert [part.members for part in group.partitions] == [(0, 2), (1,)]
    rng = np.random.default_rng(7)
    inputs = [rng.standard_normal((3, 8)).astype(np.float32) for _ in nets]
    q = forward_group(group, inputs)
    assert len(q) == 3 and len(list(q)) == 3
    for j, net in enumerate(nets):
        alone = forward_group(build_group([net]), [inputs[j]])[0]
        np.testing.assert_array_equal(q[j], alone)
        np.testing.assert_array_equal(q[j - 3], alone)
    np.testing.assert_array_equal(q.rows_from(1), np.concatenate([q[1], q[2]]))
    with pytest.raises(IndexError):
        q[3]
