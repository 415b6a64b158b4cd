"""Networks for `coexist eval --fast` when no store is given: a tiny zoo trained on the fly.

Only the goals the suite needs are trained, with the trainer's own learners and `publish_batch`
(so the models carry real lineage), at a size that takes seconds:

| population         | what                                   | alias        | seed |
|--------------------|----------------------------------------|--------------|------|
| ego task networks  | one per needed goal                    | `production` | 0    |
| impact networks    | one per needed partner goal            | `production` | 0    |
| partner population | task networks of the partners' goals   | `partners`   | 1    |
| JL                 | one per goal combination in `combos`   | `production` | 0    |

Quality gates are skipped (`evaluate=False`): tiny networks would fail them and get no alias.
The numbers such a zoo produces test the harness, not the paper. Torch runs on one thread while
it trains: for networks this small, a second thread only adds synchronisation
(`docs/performance.md`).
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace

import torch

from model_store.sql import SqlModelStore
from model_store.store import ModelStore
from trainer.config import ImpactConfig, JointConfig, TaskConfig
from trainer.learners import combos_by_size, train_impacts, train_joint, train_tasks
from trainer.publish import publish_batch
from trainer.zoo import load_partner_nets, load_task_nets

TINY = dict(
    hidden=(16,),
    total_steps=40,
    warmup_steps=8,
    envs_per_net=4,
    batch_size=32,
    replay_size=2_000,
    target_every=10,
    episode_steps=30,
)


@dataclass(frozen=True)
class TrainingTime:
    kind: str
    networks: int
    wall_s: float


def train_tiny_zoo(
    store: ModelStore,
    ego_goals: Sequence[str],
    partner_goals: Sequence[str],
    combos: Sequence[Sequence[str]],
    *,
    env: str = "particle",
    partner_alias: str = "partners",
) -> list[TrainingTime]:
    """Register a tiny zoo for the given goals (module docstring); returns the wall times."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _train(store, ego_goals, partner_goals, combos, env, partner_alias)
    finally:
        torch.set_num_threads(threads)


@contextmanager
def tiny_zoo_store(
    ego_goals: Sequence[str],
    partner_goals: Sequence[str],
    combos: Sequence[Sequence[str]],
    *,
    partner_alias: str = "partners",
) -> Iterator[SqlModelStore]:
    """A temporary SQLite store holding a tiny zoo for these goals (`train_tiny_zoo`); the
    store and its folder are gone when the block ends."""
    with tempfile.TemporaryDirectory(prefix="coexist-eval-") as tmp:
        store = SqlModelStore(f"sqlite:///{tmp}/models.db")
        try:
            train_tiny_zoo(store, ego_goals, partner_goals, combos, partner_alias=partner_alias)
            yield store
        finally:
            store.close()


def _train(
    store: ModelStore,
    ego_goals: Sequence[str],
    partner_goals: Sequence[str],
    combos: Sequence[Sequence[str]],
    env: str,
    partner_alias: str,
) -> list[TrainingTime]:
    task_cfg = replace(TaskConfig(), **TINY)  # type: ignore[arg-type]
    impact_cfg = replace(ImpactConfig(), **TINY)  # type: ignore[arg-type]
    joint_cfg = replace(JointConfig(), **TINY)  # type: ignore[arg-type]
    times = []
    tasks = sorted(set(ego_goals) | set(partner_goals))
    start = time.perf_counter()
    batch = train_tasks(tasks, task_cfg, seed=0, evaluate=False)
    publish_batch(store, batch, env=env, registered_by="coexist-eval --fast")
    times.append(TrainingTime("task", len(tasks), time.perf_counter() - start))

    impacts = sorted(set(partner_goals))
    start = time.perf_counter()
    partner_nets, _ = load_task_nets(store, env, impacts)
    batch = train_impacts(impacts, partner_nets, impact_cfg, seed=1000, evaluate=False)
    publish_batch(store, batch, env=env, registered_by="coexist-eval --fast")
    times.append(TrainingTime("impact", len(impacts), time.perf_counter() - start))

    # the partner population: another seed, its own alias (never the ego's networks)
    partners = sorted(set(partner_goals))
    batch = train_tasks(partners, task_cfg, seed=1, evaluate=False)
    publish_batch(store, batch, env=env, serve_alias=partner_alias, registered_by="coexist-eval")

    for size, group in combos_by_size(combos):
        start = time.perf_counter()
        nets, _ = load_partner_nets(store, env, group)
        batch = train_joint(group, nets, joint_cfg, seed=2000 + size)
        publish_batch(store, batch, env=env, registered_by="coexist-eval --fast")
        times.append(TrainingTime("joint", len(group), time.perf_counter() - start))
    return times
