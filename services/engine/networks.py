"""Loaded networks, the bounded LRU caches that hold them, and stacked groups evaluated in one pass.

| name            | what                                                                      |
|-----------------|---------------------------------------------------------------------------|
| `LruCache`      | a small thread-safe LRU map (a lock around each dict operation only)      |
| `LoadedNet`     | one version's spec, float32 tensors, sha256 and training temperature      |
| `load_net`      | store -> `LoadedNet` (the store verifies the sha256 on every load)        |
| `StackedGroup`  | the networks one request needs, stacked per architecture                  |
| `forward_group` | member inputs (rows_j, D) -> member Q-values (rows_j, A)                  |
| `MemberQ`       | its answer: a sequence of them; many members' rows at once (`rows_from`)  |
| `probe_net`     | the engine's own forward on probe inputs: finite Q-values, or refused     |
| `check_servable`| `probe_net` of an upload (spec + weights), before the store registers it  |

A group is split into *partitions* of members with the same spec, whose weights are stacked
once, (G, in, out) per layer. `forward_group` evaluates the members of a partition that have
the same number of input rows R together, one `policy.row_forward.row_forward` on a (G', R, D)
input: a request's impact networks (one view each per observation row) in one call, its task
network (K views per row) in another; members given the very same input array (the impact
networks of a belief's goals, all on the same partners' rows) take it once, (1, R, D).
Where the compiled forward exists it takes every call (it loads each weight once per block of
rows, fuses bias and activation, and outruns numpy's BLAS on these narrow layers at any row
count: `docs/performance.md`); without it numpy's matmul runs, stacked up to `STACK_MAX_ROWS`
rows per member and member by member beyond (a 2-D product per member reaches BLAS speed,
numpy's batched 3-D matmul does not).

Finite weights can still make a network that cannot be served: weights near float32's maximum
overflow the first layer's output to inf on any ordinary observation, so every act would fail.
`load_net` therefore runs every network it loads through `forward_group` (the very path of a
request) on `PROBE_ROWS` fixed observations spanning [-PROBE_SCALE, PROBE_SCALE] in each
coordinate, and refuses it (`UnservableNetwork`, a ValueError) unless every Q-value is finite:
such a version fails to load, so hot reload keeps the last good one. The registry runs the same
probe before it registers an upload or moves an alias (`check_servable`). An observation within
the probed range whose Q-values still overflow is the network's fault, not the client's
(`within_probe_range`).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar, overload

import numpy as np

from model_store.entities import ModelVersion
from model_store.store import ModelStore
from policy.qnet import QNetSpec, stack_numpy, tensors_from_safetensors
from policy.row_forward import COMPILED as ROW_FORWARD
from policy.row_forward import numpy_row_forward, row_forward
from services.engine.errors import EngineError, InvalidRequest, ModelUnavailable
from services.engine.messages import DEFAULT_TEMPERATURE

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

STACK_MAX_ROWS = 64  # members with more input rows than this are evaluated one by one
PROBE_ROWS = 16  # probe observations per network (`probe_inputs`)
PROBE_SCALE = 100.0  # they span [-PROBE_SCALE, PROBE_SCALE]: far beyond any env's observations


class LruCache(Generic[K, V]):
    """A bounded least-recently-used map; safe to share between threads."""

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"capacity: expected >= 1, got {capacity}")
        self.capacity = capacity
        self._data: OrderedDict[K, V] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: K) -> V | None:
        with self._lock:
            value = self._data.get(key)
            if value is not None:
                self._data.move_to_end(key)
            return value

    def get_all(self, keys: Sequence[K]) -> list[V | None]:
        """`get` of each key under one lock acquisition."""
        data, found = self._data, []
        with self._lock:
            for key in keys:
                value = data.get(key)
                if value is not None:
                    data.move_to_end(key)
                found.append(value)
        return found

    def put(self, key: K, value: V) -> None:
        with self._lock:
            self._data[key] = value
            self._data.move_to_end(key)
            while len(self._data) > self.capacity:
                self._data.popitem(last=False)

    def items(self) -> list[tuple[K, V]]:
        """A snapshot, least recently used first."""
        with self._lock:
            return list(self._data.items())

    def __len__(self) -> int:
        return len(self._data)

    def __contains__(self, key: object) -> bool:
        return key in self._data


def training_alpha(version: ModelVersion) -> float | None:
    """The temperature the network was trained with (`lineage.config["alpha"]`), if usable."""
    alpha: Any = version.lineage.config.get("alpha")
    if isinstance(alpha, int | float) and not isinstance(alpha, bool) and 0 < alpha < float("inf"):
        return float(alpha)
    return None


@dataclass(frozen=True, eq=False)
class LoadedNet:
    name: str
    version: int
    sha256: str
    spec: QNetSpec
    tensors: dict[str, np.ndarray]  # float32, named as in `QNetwork`
    alpha: float | None  # training temperature from the lineage
    # per layer the weight transposed for `x @ w`, (1, in, out), and the bias (1, 1, out): what
    # a partition's `row_weights` stack (made once here, not for every new group of networks)
    row_layers: tuple[tuple[np.ndarray, np.ndarray], ...] = field(default=(), repr=False)


class UnservableNetwork(ValueError):
    """The engine's own forward cannot turn a network's probe inputs into finite Q-values."""


def load_net(store: ModelStore, version: ModelVersion) -> LoadedNet:
    """Load, parse and probe one version. Store errors propagate; a bad spec or file is a
    ValueError, a network the engine cannot serve an `UnservableNetwork` (module docstring)."""
    spec = QNetSpec.from_json(version.spec)
    data = store.load_weights(version.name, version.version)  # re-computes and checks the sha256
    net = _net_of(
        version.name, version.version, version.sha256, spec, data, training_alpha(version)
    )
    probe_net(net)
    return net


def _net_of(
    name: str, version: int, sha256: str, spec: QNetSpec, data: bytes, alpha: float | None
) -> LoadedNet:
    tensors = tensors_from_safetensors(spec, data)
    return LoadedNet(name, version, sha256, spec, tensors, alpha, _row_layers_of(tensors, spec))


def probe_inputs(obs_dim: int) -> np.ndarray:
    """The probe observations (PROBE_ROWS, obs_dim) float32: zeros, ±1, ±PROBE_SCALE in every
    coordinate, and fixed pseudo-random rows within ±PROBE_SCALE (the same on every call)."""
    corners = np.array([0.0, 1.0, -1.0, PROBE_SCALE, -PROBE_SCALE])[:, None] * np.ones(obs_dim)
    rng = np.random.default_rng(0)
    scattered = rng.uniform(-PROBE_SCALE, PROBE_SCALE, (PROBE_ROWS - len(corners), obs_dim))
    return np.concatenate([corners, scattered]).astype(np.float32)


def within_probe_range(obs: np.ndarray) -> bool:
    """Whether every value of `obs` lies where `probe_net` checked the networks: an overflow
    there is the network's fault, not the observation's."""
    return bool(np.all(np.abs(np.asarray(obs, dtype=np.float64)) <= PROBE_SCALE))


def overflow_error(group: StackedGroup, obs: np.ndarray, field: str) -> EngineError:
    """The error for Q-values that overflowed on `obs` (the request's `field`): the client's,
    naming the field, when the observation lies beyond the probed range; otherwise the
    networks' (`ModelUnavailable`), since every network was probed on such observations."""
    if not within_probe_range(obs):
        return InvalidRequest(field, "values so large that the Q-values overflow")
    refs = ", ".join(f"{net.name}/{net.version}" for net in group.nets)
    return ModelUnavailable(
        group.nets[0].name if group.nets else None,
        f"the networks ({refs}) give Q-values that overflow on this observation, which lies "
        f"within ±{PROBE_SCALE:g} where they were checked: a network is at fault, not the input",
    )


def probe_net(net: LoadedNet) -> None:
    """`forward_group` (a request's path: stacking, the compiled forward where there is one) of
    `net` alone on `probe_inputs`; `UnservableNetwork` saying why unless every Q-value is
    finite."""
    x_RD = probe_inputs(net.spec.obs_dim)
    try:
        with np.errstate(over="ignore", invalid="ignore"):  # the numpy forward warns on inf
            q_RA = forward_group(build_group([net]), [x_RD])[0]
    except ValueError as exc:  # the forward refuses the network itself (its layers, shapes)
        raise UnservableNetwork(f"the engine's forward cannot evaluate it ({exc})") from None
    bad_R = ~np.isfinite(q_RA).all(axis=1)
    if bad_R.any():
        first = int(np.argmax(bad_R))
        largest = max(float(np.abs(t).max()) for t in net.tensors.values())
        raise UnservableNetwork(
            f"its Q-values overflow float32 on {int(bad_R.sum())} of {len(bad_R)} probe "
            f"observations within ±{PROBE_SCALE:g} (probe {first}: "
            f"{np.array2string(x_RD[first][:4], precision=3)}...), so it could not answer any "
            f"request; the largest weight magnitude is {largest:.3g}"
        )


def check_servable(spec_json: Any, weights: bytes) -> None:
    """`probe_net` of an artifact not yet stored: a ValueError (`UnservableNetwork` when it
    parses but the engine cannot serve it) naming why. The store checks the parts' form."""
    spec = QNetSpec.from_json(spec_json)
    probe_net(_net_of("upload", 0, "", spec, weights, None))


def _row_layers_of(
    tensors: dict[str, np.ndarray], spec: QNetSpec
) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """`LoadedNet.row_layers` from the tensors (names and shapes checked by `stack_numpy`)."""
    return tuple(
        (np.ascontiguousarray(w_GOI.transpose(0, 2, 1)), b_GO[:, None, :])
        for w_GOI, b_GO in stack_numpy([tensors], spec)
    )


@dataclass(frozen=True, eq=False)
class Partition:
    """Members of one spec, stacked: per layer the weights transposed for `x @ w`, (G, in, out),
    and the biases (G, 1, out), member g of the partition at index g."""

    members: tuple[int, ...]  # indices into the group's members
    spec: QNetSpec
    row_weights: list[tuple[np.ndarray, np.ndarray]]  # per layer (G, in, out), (G, 1, out)


@dataclass(frozen=True, eq=False)
class StackedGroup:
    nets: tuple[LoadedNet, ...]
    partitions: tuple[Partition, ...]
    key: tuple[tuple[str, int], ...]  # the members' (name, version), in order
    # each member's training temperature (`DEFAULT_TEMPERATURE` where its lineage has none)
    alpha_G: np.ndarray = field(repr=False)


def _row_layers(net: LoadedNet) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    return net.row_layers or _row_layers_of(net.tensors, net.spec)  # or: made without load_net


def _partition(nets: Sequence[LoadedNet], members: list[int], spec: QNetSpec) -> Partition:
    layers = [_row_layers(nets[j]) for j in members]
    row_weights = [
        # one copy per layer from the nets' own (in, out) layouts (cheaper than stacking
        # the (out, in) tensors and transposing the stack: a top-k blend makes many groups)
        (np.concatenate([n[k][0] for n in layers]), np.concatenate([n[k][1] for n in layers]))
        for k in range(len(spec.layer_sizes))
    ]
    return Partition(tuple(members), spec, row_weights)


def build_group(nets: Sequence[LoadedNet]) -> StackedGroup:
    """Stack the members' weights, one partition per distinct spec (in order of appearance)."""
    by_spec: dict[QNetSpec, list[int]] = {}
    for j, net in enumerate(nets):
        by_spec.setdefault(net.spec, []).append(j)
    partitions = tuple(_partition(nets, members, spec) for spec, members in by_spec.items())
    alpha_G = np.array([net.alpha or DEFAULT_TEMPERATURE for net in nets], dtype=np.float64)
    alpha_G.flags.writeable = False
    key = tuple((net.name, net.version) for net in nets)
    return StackedGroup(tuple(nets), partitions, key, alpha_G)


def _forward_members(
    part: Partition, x_XRD: np.ndarray, start: int, count: int, numpy_forward: bool
) -> np.ndarray:
    """Members `start` .. `start + count - 1` of the partition on x (count or 1, R, D): each
    member on its own rows, or all of them on the same rows (X = 1)."""
    rows, activation = x_XRD.shape[1], part.spec.activation
    if ROW_FORWARD and not numpy_forward:
        return row_forward(x_XRD, part.row_weights, start, count, activation)
    if rows <= STACK_MAX_ROWS:
        return numpy_row_forward(x_XRD, part.row_weights, start, count, activation)
    shared = x_XRD.shape[0] == 1
    return np.concatenate(
        [
            numpy_row_forward(
                x_XRD[0 if shared else i][None], part.row_weights, start + i, 1, activation
            )
            for i in range(count)
        ]
    )


def _runs(part: Partition, inputs: Sequence[np.ndarray]) -> list[tuple[int, int, bool]]:
    """The partition's members as runs (start, end, shared) evaluated in one call each: members
    given the same input array (a belief's impact networks, all on the same partners' rows)
    share it; other consecutive members with as many rows are stacked."""
    runs: list[tuple[int, int, bool]] = []
    members, g = part.members, 0
    while g < len(members):
        x = inputs[members[g]]
        end = g + 1
        while end < len(members) and inputs[members[end]] is x:
            end += 1
        if end - g > 1:
            runs.append((g, end, True))
            g = end
            continue
        rows = x.shape[0]
        while (
            end < len(members)
            and inputs[members[end]].shape[0] == rows
            and (end + 1 == len(members) or inputs[members[end + 1]] is not inputs[members[end]])
        ):
            end += 1
        runs.append((g, end, False))
        g = end
    return runs


class MemberQ(Sequence[np.ndarray]):
    """`forward_group`'s answer: member j's Q-values (rows_j, A) float32 at [j] (a view into
    the output of the call that served it, made when asked for), and those outputs
    (`calls`: first member, end, (members, R, A) array), so that `rows_from` hands out many
    members' rows at once. Why the views are made on demand: a belief's pass serves 35
    members in one call and its mix reads them through `rows_from`; a view per member was a
    numpy call each, for rows nobody indexed."""

    def __init__(self, count: int) -> None:
        self._count = count
        self._served: list[tuple[np.ndarray, int] | None] = [None] * count  # (output, i)
        self.calls: list[tuple[int, int, np.ndarray]] = []

    def __len__(self) -> int:
        return self._count

    def serve(self, members: Sequence[int], q_GRA: np.ndarray) -> None:
        """Members that are not consecutive, served by one call's output (`q_GRA[i]` is
        `members[i]`'s); a call serving consecutive members goes to `calls` instead."""
        for i, j in enumerate(members):
            self._served[j] = (q_GRA, i)

    @overload
    def __getitem__(self, j: int) -> np.ndarray: ...

    @overload
    def __getitem__(self, j: slice) -> list[np.ndarray]: ...

    def __getitem__(self, j: int | slice) -> np.ndarray | list[np.ndarray]:
        if isinstance(j, slice):
            return [self[k] for k in range(*j.indices(self._count))]
        if j < 0:
            j += self._count
        served = self._served[j] if 0 <= j < self._count else None
        if served is not None:
            return served[0][served[1]]
        for start, end, q_GRA in self.calls:
            if start <= j < end:
                return q_GRA[j - start]
        raise IndexError(f"member {j}: not served (members 0..{self._count - 1})")

    def rows_from(self, first: int) -> np.ndarray:
        """The rows of members `first`.. one after the other, (sum of rows_j, A): the output
        of the one call that served exactly those members, else a copy joining them."""
        for start, end, q_GRA in self.calls:
            if start == first and end == len(self):
                return q_GRA.reshape(-1, q_GRA.shape[-1])
        return np.concatenate(self[first:])


def forward_group(
    group: StackedGroup, inputs: Sequence[np.ndarray], *, numpy_forward: bool = False
) -> MemberQ:
    """Q-values (rows_j, A) float32 of every member j on its input (rows_j, obs_dim of its spec),
    as a `MemberQ`: per partition, in runs of members evaluated together (`_runs`).
    `numpy_forward`: numpy's matmul even where the compiled forward is built (an install
    without a C compiler, the tests' and benchmarks' reference)."""
    outputs = MemberQ(len(group.nets))
    for part in group.partitions:
        for g, end, shared in _runs(part, inputs):
            same = part.members[g:end]
            if shared or len(same) == 1:
                x_XRD = inputs[same[0]][None]
            else:  # np.stack's result, from one concatenate (np.stack's Python steps cost more)
                rows = inputs[same[0]].shape[0]
                x_XRD = np.concatenate([inputs[j] for j in same]).reshape(len(same), rows, -1)
            q_GRA = _forward_members(part, x_XRD, g, end - g, numpy_forward)
            if same[-1] - same[0] == len(same) - 1:  # consecutive members: found by their call
                outputs.calls.append((same[0], same[-1] + 1, q_GRA))
            else:
                outputs.serve(same, q_GRA)
    return outputs
