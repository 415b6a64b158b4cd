"""The Q-network: its JSON architecture spec, the MLP, safetensors I/O and a stacked ensemble.

The spec (stored verbatim in the model store next to the weights):

    {"format": "coexist.qnet/v1", "obs_dim": 8, "n_actions": 5,
     "hidden": [256, 128, 128], "activation": "relu", "dtype": "float32"}

Tensors, for k = 0..K with K = len(hidden) (the last layer has no activation):

| name              | shape                          |
|-------------------|--------------------------------|
| `layers.k.weight` | (out_k, in_k), torch convention|
| `layers.k.bias`   | (out_k,)                       |

with in_0 = obs_dim, out_k = hidden[k] and out_K = n_actions. `hidden` may be empty (a linear Q),
and holds at most `MAX_LAYERS - 1` widths: the serving forward (`policy/_row_forward.c`) keeps
per-layer state on the stack for at most `MAX_LAYERS` layers, so a deeper network could be
stored but never served.

| name                    | what                                                         |
|-------------------------|--------------------------------------------------------------|
| `QNetwork`              | one MLP, obs (..., obs_dim) -> q (..., n_actions)            |
| `StackedQNet`           | G MLPs of one spec, weights (G, out, in); x (G, B, D) -> (G, B, A) |
| `numpy_stacked_forward` | the stacked forward in plain numpy, for low-latency serving  |

Weights are written and read with safetensors only (never pickle). A file may hold float32,
float16 or bfloat16 tensors whatever the spec's dtype; readers get float32 numpy arrays.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
import torch
from safetensors.torch import load as load_safetensors_bytes
from safetensors.torch import save as save_safetensors_bytes
from torch import nn

__all__ = [
    "QNetSpec",
    "QNetwork",
    "StackedQNet",
    "numpy_stacked_forward",
    "qnet_from_safetensors",
    "stack_numpy",
    "tensors_from_safetensors",
    "weights_to_safetensors",
]

Activation = Literal["relu", "tanh"]
DType = Literal["float32", "float16", "bfloat16"]
ACTIVATIONS: tuple[str, ...] = ("relu", "tanh")
MAX_LAYERS = 16  # linear layers the serving forward evaluates (`MAX_LAYERS` of _row_forward.c)
TORCH_DTYPES: dict[str, torch.dtype] = {
    "float32": torch.float32,
    "float16": torch.float16,
    "bfloat16": torch.bfloat16,
}


def _positive_int(value: Any, field: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
        raise ValueError(f"{field}: expected a positive integer, got {value!r}")
    return value


@dataclass(frozen=True)
class QNetSpec:
    """Architecture of one Q-network; see the module docstring for the JSON form."""

    obs_dim: int
    n_actions: int
    hidden: tuple[int, ...] = (256, 128, 128)
    activation: Activation = "relu"
    dtype: DType = "float32"
    FORMAT: ClassVar[str] = "coexist.qnet/v1"

    def __post_init__(self) -> None:
        _positive_int(self.obs_dim, "obs_dim")
        _positive_int(self.n_actions, "n_actions")
        if not isinstance(self.hidden, tuple):
            raise ValueError(f"hidden: expected a tuple of positive integers, got {self.hidden!r}")
        if len(self.hidden) > MAX_LAYERS - 1:
            raise ValueError(
                f"hidden: at most {MAX_LAYERS - 1} hidden layers (the serving forward evaluates "
                f"at most {MAX_LAYERS} layers), got {len(self.hidden)}"
            )
        for k, width in enumerate(self.hidden):
            _positive_int(width, f"hidden[{k}]")
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation: expected one of {ACTIVATIONS}, got {self.activation!r}")
        if self.dtype not in TORCH_DTYPES:
            raise ValueError(f"dtype: expected one of {tuple(TORCH_DTYPES)}, got {self.dtype!r}")

    @property
    def layer_sizes(self) -> list[tuple[int, int]]:
        """(in, out) of each linear layer."""
        widths = [self.obs_dim, *self.hidden, self.n_actions]
        return list(itertools.pairwise(widths))

    @property
    def torch_dtype(self) -> torch.dtype:
        return TORCH_DTYPES[self.dtype]

    def to_json(self) -> dict[str, Any]:
        return {
            "format": self.FORMAT,
            "obs_dim": self.obs_dim,
            "n_actions": self.n_actions,
            "hidden": list(self.hidden),
            "activation": self.activation,
            "dtype": self.dtype,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> QNetSpec:
        """Parse the JSON form strictly: every field present, no extra field, right types."""
        if not isinstance(data, Mapping):
            raise ValueError(f"qnet spec: expected a JSON object, got {type(data).__name__}")
        fields = {"format", "obs_dim", "n_actions", "hidden", "activation", "dtype"}
        missing, extra = fields - set(data), set(data) - fields
        if missing:
            raise ValueError(f"qnet spec: missing field(s) {sorted(missing)}")
        if extra:
            raise ValueError(f"qnet spec: unknown field(s) {sorted(extra)}")
        if data["format"] != cls.FORMAT:
            raise ValueError(f"format: expected {cls.FORMAT!r}, got {data['format']!r}")
        hidden = data["hidden"]
        if not isinstance(hidden, list | tuple):
            raise ValueError(f"hidden: expected a list of positive integers, got {hidden!r}")
        for key in ("activation", "dtype"):
            if not isinstance(data[key], str):
                raise ValueError(f"{key}: expected a string, got {data[key]!r}")
        return cls(
            obs_dim=data["obs_dim"],
            n_actions=data["n_actions"],
            hidden=tuple(hidden),
            activation=data["activation"],
            dtype=data["dtype"],
        )

    def expected_shapes(self) -> dict[str, tuple[int, ...]]:
        shapes: dict[str, tuple[int, ...]] = {}
        for k, (n_in, n_out) in enumerate(self.layer_sizes):
            shapes[f"layers.{k}.weight"] = (n_out, n_in)
            shapes[f"layers.{k}.bias"] = (n_out,)
        return shapes


def _activate(x: torch.Tensor, activation: str) -> torch.Tensor:
    return torch.relu(x) if activation == "relu" else torch.tanh(x)


class QNetwork(nn.Module):
    """An MLP from observation (..., obs_dim) to one Q-value per action (..., n_actions)."""

    def __init__(self, spec: QNetSpec) -> None:
        super().__init__()
        self.spec = spec
        self.layers = nn.ModuleList(
            nn.Linear(n_in, n_out, dtype=spec.torch_dtype) for n_in, n_out in spec.layer_sizes
        )

    def forward(self, obs_BD: torch.Tensor) -> torch.Tensor:
        if obs_BD.ndim < 1 or obs_BD.shape[-1] != self.spec.obs_dim:
            raise ValueError(
                f"obs_BD: expected shape (..., {self.spec.obs_dim}), got {tuple(obs_BD.shape)}"
            )
        h = obs_BD.to(self.spec.torch_dtype)
        for k, layer in enumerate(self.layers):
            h = layer(h)
            if k < len(self.layers) - 1:
                h = _activate(h, self.spec.activation)
        return h


def weights_to_safetensors(net: QNetwork) -> bytes:
    """The network's tensors as a safetensors file, in the spec's dtype."""
    tensors = {
        name: t.detach().to(device="cpu", dtype=net.spec.torch_dtype).contiguous()
        for name, t in net.state_dict().items()
    }
    return save_safetensors_bytes(tensors)


def _check_tensor_names_and_shapes(
    spec: QNetSpec, shapes: Mapping[str, tuple[int, ...]], source: str
) -> None:
    expected = spec.expected_shapes()
    missing, extra = set(expected) - set(shapes), set(shapes) - set(expected)
    if missing:
        raise ValueError(f"{source}: missing tensor(s) {sorted(missing)}")
    if extra:
        raise ValueError(f"{source}: unexpected tensor(s) {sorted(extra)}")
    for name, shape in expected.items():
        if tuple(shapes[name]) != shape:
            raise ValueError(
                f"{source}: tensor {name!r} has shape {tuple(shapes[name])}, expected {shape}"
            )


def tensors_from_safetensors(spec: QNetSpec, data: bytes) -> dict[str, np.ndarray]:
    """Parse and validate a weights file against `spec`; float32 numpy arrays by name."""
    if not isinstance(data, bytes | bytearray | memoryview):
        raise ValueError(f"weights: expected bytes, got {type(data).__name__}")
    try:
        tensors = load_safetensors_bytes(bytes(data))
    except Exception as exc:  # the parser raises several exception types for bad files
        raise ValueError(f"weights: not a readable safetensors file ({exc})") from None
    _check_tensor_names_and_shapes(spec, {n: tuple(t.shape) for n, t in tensors.items()}, "weights")
    arrays: dict[str, np.ndarray] = {}
    for name, tensor in tensors.items():
        if tensor.dtype not in TORCH_DTYPES.values():
            raise ValueError(
                f"weights: tensor {name!r} has dtype {tensor.dtype}, "
                f"expected one of {tuple(TORCH_DTYPES)}"
            )
        as_float = tensor.to(torch.float32)
        if not bool(torch.isfinite(as_float).all()):
            raise ValueError(f"weights: tensor {name!r} holds non-finite values (NaN or inf)")
        arrays[name] = as_float.numpy()
    return arrays


def qnet_from_safetensors(spec: QNetSpec, data: bytes) -> QNetwork:
    net = QNetwork(spec)
    arrays = tensors_from_safetensors(spec, data)
    net.load_state_dict({n: torch.from_numpy(a).to(spec.torch_dtype) for n, a in arrays.items()})
    return net


class StackedQNet(nn.Module):
    """G independent MLPs of one spec evaluated in one batched pass.

    `weights[k]` is (G, out_k, in_k) and `biases[k]` is (G, out_k). Each member is initialised
    as `nn.Linear` would be (uniform in ±1/sqrt(in_k)), drawn from `generator` when given.
    """

    def __init__(
        self, spec: QNetSpec, n_members: int, generator: torch.Generator | None = None
    ) -> None:
        super().__init__()
        _positive_int(n_members, "n_members")
        self.spec = spec
        self.n_members = n_members
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for n_in, n_out in spec.layer_sizes:
            bound = 1.0 / math.sqrt(n_in)
            w = torch.empty(n_members, n_out, n_in).uniform_(-bound, bound, generator=generator)
            b = torch.empty(n_members, n_out).uniform_(-bound, bound, generator=generator)
            self.weights.append(nn.Parameter(w.to(spec.torch_dtype)))
            self.biases.append(nn.Parameter(b.to(spec.torch_dtype)))

    def forward(self, x_GBD: torch.Tensor) -> torch.Tensor:
        """(G, B, obs_dim) -> (G, B, n_actions); a (B, obs_dim) input is shared by all members."""
        if x_GBD.ndim == 2:
            x_GBD = x_GBD.unsqueeze(0).expand(self.n_members, -1, -1)
        if x_GBD.ndim != 3 or x_GBD.shape[0] != self.n_members:
            raise ValueError(
                f"x_GBD: expected shape ({self.n_members}, B, {self.spec.obs_dim}), "
                f"got {tuple(x_GBD.shape)}"
            )
        if x_GBD.shape[2] != self.spec.obs_dim:
            raise ValueError(
                f"x_GBD: expected last dimension {self.spec.obs_dim}, got {tuple(x_GBD.shape)}"
            )
        h = x_GBD.to(self.spec.torch_dtype)
        last = len(self.weights) - 1
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = torch.baddbmm(b.unsqueeze(1), h, w.transpose(1, 2))
            if k < last:  # in place: autograd's backward of relu and tanh reads their output
                h = h.relu_() if self.spec.activation == "relu" else h.tanh_()
        return h

    def _check_member(self, g: int) -> None:
        if not 0 <= g < self.n_members:
            raise ValueError(f"g: member index {g} out of range 0..{self.n_members - 1}")

    def member_state(self, g: int) -> dict[str, torch.Tensor]:
        """Member g's tensors, named as in `QNetwork` (detached copies)."""
        self._check_member(g)
        state: dict[str, torch.Tensor] = {}
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            state[f"layers.{k}.weight"] = w[g].detach().clone()
            state[f"layers.{k}.bias"] = b[g].detach().clone()
        return state

    def load_member(self, g: int, state: Mapping[str, torch.Tensor]) -> None:
        """Overwrite member g with tensors named and shaped as in `QNetwork`."""
        self._check_member(g)
        _check_tensor_names_and_shapes(
            self.spec, {n: tuple(t.shape) for n, t in state.items()}, f"member {g} state"
        )
        with torch.no_grad():
            for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
                w[g].copy_(state[f"layers.{k}.weight"])
                b[g].copy_(state[f"layers.{k}.bias"])

    @classmethod
    def from_members(
        cls, spec: QNetSpec, states: Sequence[Mapping[str, torch.Tensor]]
    ) -> StackedQNet:
        stacked = cls(spec, len(states))
        for g, state in enumerate(states):
            stacked.load_member(g, state)
        return stacked


def stack_numpy(
    tensors_list: Sequence[Mapping[str, np.ndarray]], spec: QNetSpec
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per layer, the members' (weight (G, out, in), bias (G, out)) stacked, float32."""
    if len(tensors_list) == 0:
        raise ValueError("tensors_list: expected at least one member")
    for g, tensors in enumerate(tensors_list):
        _check_tensor_names_and_shapes(
            spec, {n: np.shape(a) for n, a in tensors.items()}, f"member {g}"
        )
    return [
        (
            np.stack([np.asarray(t[f"layers.{k}.weight"], np.float32) for t in tensors_list]),
            np.stack([np.asarray(t[f"layers.{k}.bias"], np.float32) for t in tensors_list]),
        )
        for k in range(len(spec.layer_sizes))
    ]


def numpy_stacked_forward(
    weights: Sequence[tuple[np.ndarray, np.ndarray]], x_GBD: np.ndarray, activation: str
) -> np.ndarray:
    """The `StackedQNet` forward in numpy: (G, B, D) -> (G, B, A), in the weights' dtype."""
    if activation not in ACTIVATIONS:
        raise ValueError(f"activation: expected one of {ACTIVATIONS}, got {activation!r}")
    if len(weights) == 0:
        raise ValueError("weights: expected at least one layer")
    w0 = weights[0][0]
    h = np.asarray(x_GBD, dtype=w0.dtype)
    if h.ndim != 3 or h.shape[0] != w0.shape[0] or h.shape[2] != w0.shape[2]:
        raise ValueError(f"x_GBD: expected shape ({w0.shape[0]}, B, {w0.shape[2]}), got {h.shape}")
    for k, (w_GOI, b_GO) in enumerate(weights):
        h = np.matmul(h, w_GOI.transpose(0, 2, 1))
        h += b_GO[:, None, :]  # in place: at large batches each temporary is memory traffic
        if k < len(weights) - 1:
            if activation == "relu":
                np.maximum(h, 0.0, out=h)
            else:
                np.tanh(h, out=h)
    return h
