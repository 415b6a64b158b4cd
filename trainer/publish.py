"""Register trained networks in the model store, with their lineage (issue: model store).

Every member of a `TrainedBatch` becomes one version of its model (`particle/task/a3`, ...):
architecture spec + safetensors weights, and a lineage holding the training config, seed, code
version, metrics (gate results, curve summary, the whole training curve as `training_curve`:
steps, mean return, loss) and the parent versions it was trained against.
The `latest` alias always moves; `production` (or the run's serve alias) moves only when the
network passed its gate. The
gate verdict is also written as the model's `gate` tag so `coexist models list` shows it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from model_store.entities import Lineage, ModelVersion
from model_store.lineage import code_version
from model_store.naming import impact_model_name, joint_model_name, task_model_name
from model_store.store import ModelStore
from policy.qnet import QNetwork, weights_to_safetensors
from trainer.learners import TrainedBatch


def model_name(env: str, kind: str, goals: Sequence[str]) -> str:
    if kind == "task":
        return task_model_name(env, goals[0])
    if kind == "impact":
        return impact_model_name(env, goals[0])
    return joint_model_name(env, goals[0], list(goals[1:]))


def publish_batch(
    store: ModelStore,
    batch: TrainedBatch,
    *,
    env: str = "particle",
    parents: Mapping[tuple[str, ...], Sequence[str]] | None = None,
    registered_by: str = "coexist-trainer",
    extra_config: Mapping[str, object] | None = None,
    serve_alias: str = "production",
) -> list[ModelVersion]:
    """Register every network of `batch`; returns the new versions in member order.

    `serve_alias` is the alias a network that passed its gate receives (`production` for the
    zoo that is served; e.g. `partners` for a separately trained partner population)."""
    versions = []
    config = {**batch.config.to_dict(), "kind": batch.kind, **(extra_config or {})}
    for g, goals in enumerate(batch.goals):
        name = model_name(env, batch.kind, goals)
        store.create_model(
            name,
            env=env,
            kind=batch.kind,
            goals=tuple(goals),
            obs_dim=batch.spec.obs_dim,
            n_actions=batch.spec.n_actions,
            description=_describe(batch.kind, goals),
            exist_ok=True,
        )
        net = QNetwork(batch.spec)
        net.load_state_dict(batch.nets.member_state(g))
        passed = batch.gate_passed(g)
        metrics: dict[str, object] = {"curve": batch.curve_summary(g)}
        if batch.curves.steps:
            metrics["training_curve"] = batch.curve_series(g)
        gate = batch.gates[g] if batch.gates else None
        if gate is not None:
            metrics["gate"] = gate.metrics()
        lineage = Lineage(
            config=config,
            seed=batch.seed,
            code_version=code_version(),
            metrics=metrics,
            parents=tuple((parents or {}).get(tuple(goals), ())),
            registered_by=registered_by,
        )
        aliases = ("latest", serve_alias) if passed in (True, None) else ("latest",)
        version = store.register_version(
            name,
            spec=batch.spec.to_json(),
            weights=weights_to_safetensors(net),
            lineage=lineage,
            aliases=aliases,
        )
        verdict = "none" if passed is None else ("passed" if passed else "failed")
        store.update_model(name, tags={"gate": verdict, "seed": str(batch.seed)})
        versions.append(version)
    return versions


def _describe(kind: str, goals: Sequence[str]) -> str:
    if kind == "task":
        return f"Task network: reach goal {goals[0]} (soft-Q, eqs. 3-5)."
    if kind == "impact":
        return f"Impact network: help a partner whose goal is {goals[0]} (self-play, eqs. 6-7)."
    return f"Joint-learner baseline for ego {goals[0]} with partners {', '.join(goals[1:])}."
