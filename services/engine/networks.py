"""Loaded networks, the bounded LRU caches that hold them, and stacked groups evaluated in one pass.

| name            | what                                                                      |
|-----------------|---------------------------------------------------------------------------|
| `LruCache`      | a small thread-safe LRU map (a lock around each dict operation only)      |
| `LoadedNet`     | one version's spec, float32 tensors, sha256 and training temperature      |
| `load_net`      | store -> `LoadedNet` (the store verifies the sha256 on every load)        |
| `StackedGroup`  | the networks one request needs, stacked per architecture                  |
| `forward_group` | member inputs (rows_j, D) -> member Q-values (rows_j, A)                  |
| `forward_rows`  | one observation row: R one-row members -> (R, 1, A) (`fastpath`)         |

A group is split into *partitions* of members with the same spec. A partition whose members have
at most `STACK_MAX_ROWS` input rows each is evaluated by one `numpy_stacked_forward` on a
(G, R, D) input, R the largest member's row count, smaller members padded with zero rows (their
outputs are cut off again): at small batches the per-call overhead dominates, and one pass pays it
once. Larger partitions are evaluated member by member (G = 1 slices of the same stacked weights,
no padding): numpy's batched 3-D matmul does not reach BLAS speed, one 2-D product per member
does, so at batch 256 the members' BLAS calls win. A single observation row is cheapest as R
one-row members (K task views + one view per impact net): R matrix-vector products in one
stacked call, ~2x faster than the padded (G, K, D) stack (`forward_rows`, `Partition`).
Where `policy.row_forward` is compiled, `forward_rows` and every partition of at most
`ROW_FORWARD_MAX_ROWS` rows per member run in its single C loop (each weight read once) instead
of numpy's matmul.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np

from model_store.entities import ModelVersion
from model_store.store import ModelStore
from policy.qnet import QNetSpec, numpy_stacked_forward, stack_numpy, tensors_from_safetensors
from policy.row_forward import COMPILED as ROW_FORWARD
from policy.row_forward import row_forward

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

STACK_MAX_ROWS = 64  # members with more input rows than this are evaluated one by one
ROW_FORWARD_MAX_ROWS = 8  # members with at most this many rows: `policy.row_forward` when compiled
ROW_REPEAT_MAX_BYTES = 8 << 20  # at most this much extra memory for `Partition.row_weights`


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


def load_net(store: ModelStore, version: ModelVersion) -> LoadedNet:
    """Load and parse one version. Store errors propagate; a bad spec or file is a ValueError."""
    spec = QNetSpec.from_json(version.spec)
    data = store.load_weights(version.name, version.version)  # re-computes and checks the sha256
    tensors = tensors_from_safetensors(spec, data)
    return LoadedNet(
        version.name, version.version, version.sha256, spec, tensors, training_alpha(version),
        _row_layers_of(tensors, spec),
    )  # fmt: skip


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
    """Members of one spec, stacked. `row_weights` holds, per layer, (R, in, out) weights and
    (R, 1, out) biases with the first member repeated `first_repeats` times (R = repeats + G - 1),
    transposed for `x @ w`: a single observation row (K task views, one view per impact net)
    is then one stacked forward of R one-row members over a slice, with no copy (`forward_rows`).
    `weights` are views of the same memory in the (G, out, in) layout of `stack_numpy`."""

    members: tuple[int, ...]  # indices into the group's members
    spec: QNetSpec
    weights: list[tuple[np.ndarray, np.ndarray]]  # per layer (G, out, in), (G, out)
    row_weights: list[tuple[np.ndarray, np.ndarray]]  # per layer (R, in, out), (R, 1, out)
    first_repeats: int


@dataclass(frozen=True, eq=False)
class StackedGroup:
    nets: tuple[LoadedNet, ...]
    partitions: tuple[Partition, ...]
    # per request layout: derived look-up tables (`services.engine.fastpath`), bounded
    memo: dict[Hashable, Any] = field(default_factory=dict, repr=False)


def _row_layers(net: LoadedNet) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    return net.row_layers or _row_layers_of(net.tensors, net.spec)  # or: made without load_net


def _partition(
    nets: Sequence[LoadedNet], members: list[int], spec: QNetSpec, repeats: int
) -> Partition:
    layers = [_row_layers(nets[j]) for j in members]
    layer_bytes = sum(w.nbytes + b.nbytes for w, b in layers[0])
    if (repeats - 1) * layer_bytes > ROW_REPEAT_MAX_BYTES:
        repeats = 1  # too big to copy: a single row with several task views takes the general path
    row_weights, weights = [], []
    for k in range(len(spec.layer_sizes)):
        # one copy per layer from the nets' own (in, out) layouts (~4x cheaper than stacking
        # the (out, in) tensors and transposing the stack: a top-k blend makes many groups)
        w_RIO = np.concatenate([layers[0][k][0]] * (repeats - 1) + [n[k][0] for n in layers])
        b_R1O = np.concatenate([layers[0][k][1]] * (repeats - 1) + [n[k][1] for n in layers])
        row_weights.append((w_RIO, b_R1O))
        weights.append((w_RIO[repeats - 1 :].transpose(0, 2, 1), b_R1O[repeats - 1 :, 0, :]))
    return Partition(tuple(members), spec, weights, row_weights, repeats)


def build_group(nets: Sequence[LoadedNet], first_repeats: int = 1) -> StackedGroup:
    """Stack the members' weights, one partition per distinct spec (in order of appearance);
    member 0 (the task network) is repeated `first_repeats` times in `row_weights`."""
    by_spec: dict[QNetSpec, list[int]] = {}
    for j, net in enumerate(nets):
        by_spec.setdefault(net.spec, []).append(j)
    partitions = tuple(
        _partition(nets, members, spec, max(first_repeats, 1) if members[0] == 0 else 1)
        for spec, members in by_spec.items()
    )
    return StackedGroup(tuple(nets), partitions)


def forward_rows(part: Partition, x_R1D: np.ndarray, first_rows: int) -> np.ndarray:
    """One-row members: x (R, 1, in) whose first `first_rows` rows go through the partition's
    first member and the others through one member each, in order -> q (R, 1, A). Needs
    `first_rows <= part.first_repeats`. At batch 1 this beats a padded (G, K, in) stack: the
    R matrix-vector products run in one loop (`policy.row_forward`, compiled where it can)."""
    start = part.first_repeats - first_rows
    members = len(part.row_weights[0][0]) - start
    return row_forward(x_R1D, part.row_weights, start, members, part.spec.activation)


def _forward_partition(part: Partition, inputs: Sequence[np.ndarray]) -> list[np.ndarray]:
    rows = [inputs[j].shape[0] for j in part.members]
    activation = part.spec.activation
    if max(rows) > STACK_MAX_ROWS and len(rows) > 1:
        return [
            numpy_stacked_forward(
                [(w[g : g + 1], b[g : g + 1]) for w, b in part.weights], inputs[j][None], activation
            )[0]
            for g, j in enumerate(part.members)
        ]
    if min(rows) == max(rows):
        x_GRD = np.stack([inputs[j] for j in part.members])
    else:
        x_GRD = np.zeros((len(rows), max(rows), part.spec.obs_dim), dtype=np.float32)
        for g, j in enumerate(part.members):
            x_GRD[g, : rows[g]] = inputs[j]
    if ROW_FORWARD and max(rows) <= ROW_FORWARD_MAX_ROWS:  # a few rows: one compiled loop
        start = part.first_repeats - 1  # the first member's own copy in `row_weights`
        q_GRA = row_forward(x_GRD, part.row_weights, start, len(rows), activation)
    else:
        q_GRA = numpy_stacked_forward(part.weights, x_GRD, activation)
    return [q_GRA[g, : rows[g]] for g in range(len(rows))]


def forward_group(group: StackedGroup, inputs: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Q-values (rows_j, A) of every member j on its input (rows_j, obs_dim of its spec)."""
    outputs: list[np.ndarray] = [np.empty(0)] * len(group.nets)
    for part in group.partitions:
        for j, q in zip(part.members, _forward_partition(part, inputs), strict=True):
            outputs[j] = q
    return outputs
