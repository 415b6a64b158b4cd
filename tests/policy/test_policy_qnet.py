"""policy.qnet: the JSON spec, QNetwork, StackedQNet, numpy serving path and safetensors checks."""

from __future__ import annotations

import json
import struct
from typing import Any

import numpy as np
import pytest
import safetensors.torch
import torch

from policy.qnet import (
    QNetSpec,
    QNetwork,
    StackedQNet,
    numpy_stacked_forward,
    qnet_from_safetensors,
    stack_numpy,
    tensors_from_safetensors,
    weights_to_safetensors,
)

SPEC = QNetSpec(obs_dim=8, n_actions=5, hidden=(16, 12))

# --- the JSON spec --------------------------------------------------------------------------


def test_spec_json_round_trip_and_shapes() -> None:
    data = SPEC.to_json()
    assert data == {
        "format": "coexist.qnet/v1",
        "obs_dim": 8,
        "n_actions": 5,
        "hidden": [16, 12],
        "activation": "relu",
        "dtype": "float32",
    }
    assert QNetSpec.from_json(json.loads(json.dumps(data))) == SPEC
    assert SPEC.expected_shapes() == {
        "layers.0.weight": (16, 8),
        "layers.0.bias": (16,),
        "layers.1.weight": (12, 16),
        "layers.1.bias": (12,),
        "layers.2.weight": (5, 12),
        "layers.2.bias": (5,),
    }
    linear = QNetSpec(obs_dim=3, n_actions=2, hidden=())
    assert linear.expected_shapes() == {"layers.0.weight": (2, 3), "layers.0.bias": (2,)}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"format": "coexist.qnet/v2"}, "format: expected 'coexist.qnet/v1'"),
        ({"obs_dim": 0}, "obs_dim: expected a positive integer"),
        ({"obs_dim": 8.0}, "obs_dim: expected a positive integer"),
        ({"n_actions": True}, "n_actions: expected a positive integer"),
        ({"n_actions": "5"}, "n_actions: expected a positive integer"),
        ({"hidden": 16}, "hidden: expected a list"),
        ({"hidden": [16, -1]}, r"hidden\[1\]: expected a positive integer"),
        ({"activation": "gelu"}, "activation: expected one of"),
        ({"activation": 3}, "activation: expected a string"),
        ({"dtype": "int8"}, "dtype: expected one of"),
        ({"extra": 1}, r"unknown field\(s\) \['extra'\]"),
    ],
)
def test_spec_from_json_rejects_bad_fields(change: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        QNetSpec.from_json({**SPEC.to_json(), **change})


def test_spec_from_json_rejects_missing_fields_and_non_objects() -> None:
    data = SPEC.to_json()
    del data["activation"]
    with pytest.raises(ValueError, match=r"missing field\(s\) \['activation'\]"):
        QNetSpec.from_json(data)
    with pytest.raises(ValueError, match="expected a JSON object"):
        QNetSpec.from_json([1, 2])  # type: ignore[arg-type]


# --- networks -------------------------------------------------------------------------------


def test_qnetwork_forward_shape_and_bad_input() -> None:
    net = QNetwork(QNetSpec(obs_dim=8, n_actions=5, hidden=(16,), activation="tanh"))
    assert [name for name, _ in net.named_parameters()] == list(net.spec.expected_shapes())
    assert net(torch.zeros(3, 8)).shape == (3, 5)
    with pytest.raises(ValueError, match=r"obs_BD: expected shape \(\.\.\., 8\)"):
        net(torch.zeros(3, 7))


@pytest.mark.parametrize("activation", ["relu", "tanh"])
def test_stacked_member_equals_single_network(activation: str) -> None:
    spec = QNetSpec(obs_dim=8, n_actions=5, hidden=(16, 12), activation=activation)  # type: ignore[arg-type]
    stacked = StackedQNet(spec, 4, torch.Generator().manual_seed(0))
    x = torch.randn(4, 10, 8, generator=torch.Generator().manual_seed(1))
    q_GBA = stacked(x)
    assert q_GBA.shape == (4, 10, 5)
    for g in range(4):
        single = QNetwork(spec)
        single.load_state_dict(stacked.member_state(g))
        torch.testing.assert_close(single(x[g]), q_GBA[g], atol=1e-6, rtol=1e-6)
    # a (B, D) input is shared by all members
    torch.testing.assert_close(stacked(x[0])[2], stacked(x[0].expand(4, 10, 8))[2])


def test_stacked_init_is_seeded_like_nn_linear() -> None:
    a = StackedQNet(SPEC, 3, torch.Generator().manual_seed(7))
    b = StackedQNet(SPEC, 3, torch.Generator().manual_seed(7))
    c = StackedQNet(SPEC, 3, torch.Generator().manual_seed(8))
    assert all(torch.equal(p, q) for p, q in zip(a.parameters(), b.parameters(), strict=True))
    assert not torch.equal(a.weights[0], c.weights[0])
    assert not torch.equal(a.weights[0][0], a.weights[0][1])  # members differ
    bound = 1 / np.sqrt(8)  # fan_in of layer 0
    assert a.weights[0].abs().max() <= bound and a.weights[0].abs().max() > 0.8 * bound


def test_stacked_load_member_and_from_members() -> None:
    nets = [QNetwork(SPEC) for _ in range(3)]
    stacked = StackedQNet.from_members(SPEC, [n.state_dict() for n in nets])
    x = torch.randn(6, 8)
    for g, net in enumerate(nets):
        torch.testing.assert_close(stacked(x)[g], net(x), atol=1e-6, rtol=1e-6)
    stacked.load_member(1, nets[2].state_dict())
    torch.testing.assert_close(stacked(x)[1], nets[2](x), atol=1e-6, rtol=1e-6)
    bad = dict(nets[0].state_dict())
    bad["layers.0.weight"] = torch.zeros(16, 9)
    with pytest.raises(ValueError, match=r"member 0 state: tensor 'layers.0.weight' has shape"):
        stacked.load_member(0, bad)
    with pytest.raises(ValueError, match="g: member index 3 out of range"):
        stacked.member_state(3)
    with pytest.raises(ValueError, match=r"x_GBD: expected shape \(3, B, 8\)"):
        stacked(torch.zeros(2, 4, 8))


def test_numpy_stacked_forward_matches_torch() -> None:
    for activation in ("relu", "tanh"):
        spec = QNetSpec(obs_dim=8, n_actions=5, hidden=(16, 12), activation=activation)
        nets = [QNetwork(spec) for _ in range(3)]
        stacked = StackedQNet.from_members(spec, [n.state_dict() for n in nets])
        tensors = [tensors_from_safetensors(spec, weights_to_safetensors(n)) for n in nets]
        weights = stack_numpy(tensors, spec)
        assert weights[0][0].shape == (3, 16, 8) and weights[0][0].dtype == np.float32
        x = np.random.default_rng(0).normal(size=(3, 7, 8)).astype(np.float32)
        q_np = numpy_stacked_forward(weights, x, activation)
        with torch.no_grad():
            q_torch = stacked(torch.from_numpy(x)).numpy()
        np.testing.assert_allclose(q_np, q_torch, atol=1e-6, rtol=1e-5)
    with pytest.raises(ValueError, match=r"x_GBD: expected shape \(3, B, 8\)"):
        numpy_stacked_forward(weights, np.zeros((3, 7, 9)), "relu")
    with pytest.raises(ValueError, match="activation"):
        numpy_stacked_forward(weights, x, "gelu")
    with pytest.raises(ValueError, match="member 1: missing tensor"):
        stack_numpy([tensors[0], {}], spec)


# --- safetensors ----------------------------------------------------------------------------


@pytest.mark.parametrize("dtype", ["float32", "float16", "bfloat16"])
def test_safetensors_round_trip(dtype: str) -> None:
    spec = QNetSpec(obs_dim=8, n_actions=5, hidden=(16,), dtype=dtype)  # type: ignore[arg-type]
    net = QNetwork(spec)
    data = weights_to_safetensors(net)
    arrays = tensors_from_safetensors(spec, data)
    assert set(arrays) == set(spec.expected_shapes())
    assert all(a.dtype == np.float32 for a in arrays.values())
    loaded = qnet_from_safetensors(spec, data)
    for name, tensor in net.state_dict().items():
        assert torch.equal(loaded.state_dict()[name], tensor)
    x = torch.randn(4, 8)
    assert torch.equal(loaded(x), net(x))


def _file(tensors: dict[str, torch.Tensor]) -> bytes:
    return safetensors.torch.save(tensors)


def _good_tensors() -> dict[str, torch.Tensor]:
    return {n: t.clone() for n, t in QNetwork(SPEC).state_dict().items()}


def test_corrupt_or_truncated_bytes_are_rejected() -> None:
    data = weights_to_safetensors(QNetwork(SPEC))
    for bad in (b"", b"not safetensors at all", data[: len(data) // 2], data[:7]):
        with pytest.raises(ValueError, match="weights: not a readable safetensors file"):
            tensors_from_safetensors(SPEC, bad)
    lying_header = struct.pack("<Q", 10**9) + data[8:]
    with pytest.raises(ValueError, match="weights: not a readable safetensors file"):
        tensors_from_safetensors(SPEC, lying_header)
    with pytest.raises(ValueError, match="weights: expected bytes"):
        tensors_from_safetensors(SPEC, "text")  # type: ignore[arg-type]


def test_wrong_tensor_sets_shapes_dtypes_and_values_are_rejected() -> None:
    missing = _good_tensors()
    del missing["layers.2.bias"]
    with pytest.raises(ValueError, match=r"missing tensor\(s\) \['layers.2.bias'\]"):
        tensors_from_safetensors(SPEC, _file(missing))

    extra = {**_good_tensors(), "layers.3.weight": torch.zeros(2, 2)}
    with pytest.raises(ValueError, match=r"unexpected tensor\(s\) \['layers.3.weight'\]"):
        tensors_from_safetensors(SPEC, _file(extra))

    wrong_shape = {**_good_tensors(), "layers.1.weight": torch.zeros(16, 12)}
    with pytest.raises(
        ValueError, match=r"'layers.1.weight' has shape \(16, 12\), expected \(12, 16\)"
    ):
        tensors_from_safetensors(SPEC, _file(wrong_shape))

    int_dtype = {**_good_tensors(), "layers.0.bias": torch.zeros(16, dtype=torch.int32)}
    with pytest.raises(ValueError, match=r"'layers.0.bias' has dtype torch.int32"):
        tensors_from_safetensors(SPEC, _file(int_dtype))

    double = {**_good_tensors(), "layers.0.bias": torch.zeros(16, dtype=torch.float64)}
    with pytest.raises(ValueError, match=r"'layers.0.bias' has dtype torch.float64"):
        tensors_from_safetensors(SPEC, _file(double))

    for bad_value in (float("nan"), float("inf")):
        poisoned = _good_tensors()
        poisoned["layers.1.weight"][3, 4] = bad_value
        with pytest.raises(ValueError, match=r"'layers.1.weight' holds non-finite"):
            tensors_from_safetensors(SPEC, _file(poisoned))

    # the same tensors under a spec of another shape
    other = QNetSpec(obs_dim=8, n_actions=4, hidden=(16, 12))
    with pytest.raises(ValueError, match=r"'layers.2.weight' has shape"):
        qnet_from_safetensors(other, _file(_good_tensors()))
