"""Loaded networks, the bounded LRU caches that hold them, and stacked groups evaluated in one pass.

| name            | what                                                                      |
|-----------------|---------------------------------------------------------------------------|
| `LruCache`      | a small thread-safe LRU map (a lock around each dict operation only)      |
| `LoadedNet`     | one version's spec, float32 tensors, sha256 and training temperature      |
| `load_net`      | store -> `LoadedNet` (the store verifies the sha256 on every load)        |
| `StackedGroup`  | the networks one request needs, stacked per architecture                  |
| `forward_group` | member inputs (rows_j, D) -> member Q-values (rows_j, A)                  |

A group is split into *partitions* of members with the same spec. A partition whose members have
at most `STACK_MAX_ROWS` input rows each is evaluated by one `numpy_stacked_forward` on a
(G, R, D) input, R the largest member's row count, smaller members padded with zero rows (their
outputs are cut off again): at small batches the per-call overhead dominates, and one pass pays it
once. Larger partitions are evaluated member by member (G = 1 slices of the same stacked weights,
no padding): numpy's batched 3-D matmul does not reach BLAS speed, one 2-D product per member
does, so at batch 256 the members' BLAS calls win.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np

from model_store.entities import ModelVersion
from model_store.store import ModelStore
from policy.qnet import QNetSpec, numpy_stacked_forward, stack_numpy, tensors_from_safetensors

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

STACK_MAX_ROWS = 64  # members with more input rows than this are evaluated one by one


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


def load_net(store: ModelStore, version: ModelVersion) -> LoadedNet:
    """Load and parse one version. Store errors propagate; a bad spec or file is a ValueError."""
    spec = QNetSpec.from_json(version.spec)
    data = store.load_weights(version.name, version.version)  # re-computes and checks the sha256
    tensors = tensors_from_safetensors(spec, data)
    return LoadedNet(
        version.name, version.version, version.sha256, spec, tensors, training_alpha(version)
    )


@dataclass(frozen=True, eq=False)
class Partition:
    members: tuple[int, ...]  # indices into the group's members
    spec: QNetSpec
    weights: list[tuple[np.ndarray, np.ndarray]]  # per layer (G, out, in), (G, out)


@dataclass(frozen=True, eq=False)
class StackedGroup:
    nets: tuple[LoadedNet, ...]
    partitions: tuple[Partition, ...]


def build_group(nets: Sequence[LoadedNet]) -> StackedGroup:
    """Stack the members' weights, one partition per distinct spec (in order of appearance)."""
    by_spec: dict[QNetSpec, list[int]] = {}
    for j, net in enumerate(nets):
        by_spec.setdefault(net.spec, []).append(j)
    partitions = tuple(
        Partition(tuple(members), spec, stack_numpy([nets[j].tensors for j in members], spec))
        for spec, members in by_spec.items()
    )
    return StackedGroup(tuple(nets), partitions)


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
    q_GRA = numpy_stacked_forward(part.weights, x_GRD, activation)
    return [q_GRA[g, : rows[g]] for g in range(len(rows))]


def forward_group(group: StackedGroup, inputs: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Q-values (rows_j, A) of every member j on its input (rows_j, obs_dim of its spec)."""
    outputs: list[np.ndarray] = [np.empty(0)] * len(group.nets)
    for part in group.partitions:
        for j, q in zip(part.members, _forward_partition(part, inputs), strict=True):
            outputs[j] = q
    return outputs
