"""Claim 4: how many networks each method needs, and what one network costs to train.

Networks to cover every goal combination of N agents with |G| = 35 goals (paper §4.2):

| method    | networks          | why                                                          |
|-----------|-------------------|--------------------------------------------------------------|
| SL        | |G|               | one task network per goal; ignores the others                |
| NAIL/AAIL | 2 |G|             | one task + one impact network per goal, for any N (pair views)|
| JL        | |G|^N            | one joint network per ordered (ego, partner 1, ...) combination|

Training cost per network comes from the store: every registered version's lineage holds its
config (batched steps `total_steps`, `envs_per_net` environments per network, one update per
step after `warmup_steps`) and, when a timing log is given (`evaluation.timing`), the measured
wall time of the commands that trained them. Networks of one kind train side by side in batches,
so "wall time per network" is the batch's wall time divided by its networks.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

from evaluation.timing import KindCost, LoggedCommand, attribute_wall_times
from model_store.entities import ModelVersion, RegisteredModel
from model_store.store import ModelStore

KINDS: tuple[str, ...] = ("task", "impact", "joint")


def networks_needed(n_goals: int, n_agents: int) -> dict[str, int]:
    """Networks each method needs to cover all goal combinations of `n_agents` agents."""
    if n_goals < 1 or n_agents < 1:
        raise ValueError(f"n_goals, n_agents: expected >= 1, got {n_goals}, {n_agents}")
    interaction = 2 * n_goals if n_agents > 1 else n_goals
    return {"sl": n_goals, "nail": interaction, "aail": interaction, "jl": n_goals**n_agents}


@dataclass(frozen=True)
class KindTraining:
    """What the registered networks of one kind cost to train."""

    kind: str
    versions: int  # registered versions of this kind in the store
    steps: float  # mean batched env steps per network
    transitions: float  # mean env transitions per network (steps x envs_per_net)
    updates: float  # mean gradient updates per network
    hidden: str  # architectures seen
    wall: KindCost | None  # measured, when the timing log covers this kind


def _models(store: ModelStore, env: str) -> Iterator[RegisteredModel]:
    token: str | None = None
    while True:
        page = store.list_models(env=env, page_size=200, page_token=token)
        yield from page.items
        token = page.next_page_token
        if token is None:
            return


def registered_versions(store: ModelStore, env: str) -> list[tuple[str, ModelVersion]]:
    """(kind, version) of every ready version of every model of `env`."""
    out = []
    for model in _models(store, env):
        for version in store.list_versions(model.name, include_archived=False):
            out.append((model.kind, version))
    return out


def _mean(values: Sequence[float]) -> float:
    return sum(values) / len(values) if values else float("nan")


def training_costs(
    versions: Sequence[tuple[str, ModelVersion]], log: Sequence[LoggedCommand]
) -> list[KindTraining]:
    walls = attribute_wall_times(log, versions)
    rows = []
    for kind in KINDS:
        configs = [v.lineage.config for k, v in versions if k == kind]
        if not configs:
            continue
        steps = [float(c.get("total_steps", 0)) for c in configs]
        envs = [float(c.get("envs_per_net", 1)) for c in configs]
        warmup = [float(c.get("warmup_steps", 0)) for c in configs]
        per_step = [float(c.get("updates_per_step", 1)) for c in configs]
        hidden = sorted({"-".join(str(h) for h in c.get("hidden", [])) or "?" for c in configs})
        rows.append(
            KindTraining(
                kind=kind,
                versions=len(configs),
                steps=_mean(steps),
                transitions=_mean([s * e for s, e in zip(steps, envs, strict=True)]),
                updates=_mean(
                    [max(s - w, 0) * u for s, w, u in zip(steps, warmup, per_step, strict=True)]
                ),
                hidden=", ".join(hidden),
                wall=walls.get(kind),
            )
        )
    return rows
