"""Training work cut into self-contained batch jobs, for backends that run them elsewhere.

A `BatchJob` is what `trainer.zoo`'s loops do for one batch of goals, made portable: it names
its goals, its seed and its `RunState` key, and `train_batch(store_url, job, config, ...)` does the
whole batch inside any process that can reach the store: load the registered task networks it
depends on (impact, joint), train, and register the networks with `publish_once` (lineage as the
local backend writes it, plus the job marker `config["job"]`). It returns a `BatchOutcome`: the
registered refs, gates and curves for the summary table and plots; never weights (they travel
through the store as safetensors only).

| kind       | members of one job                   | seed (as in `trainer.zoo`) | run key            |
|------------|--------------------------------------|----------------------------|--------------------|
| task       | up to `goals_per_batch` goals        | seed + batch index         | `task:a2,b3`       |
| task retry | the goals whose network failed its   | seed + 7919 x attempt + i  | `task-retry-1:0`   |
|            | gate, twice each, in two halves i    |                            | `task-retry-1:1`   |
| impact     | up to `goals_per_batch` goals        | seed + 1000 + batch index  | `impact:a2,b3`     |
| impact retry | as the task retry                  | seed + 1000 + 7919 x attempt + i | `impact-retry-1:0` |
| joint      | every combination of one size        | seed + 2000 + size         | `joint:a2+b3;c+c4` |

Stages run in order (tasks and their gate retries, then impacts, then joint): an impact job
needs the task versions registered before it, exactly as in the local pipeline (and in the
kitchen a `production` one: `impact_jobs_with_parents` drops the other goals, as
`trainer.zoo.run_impacts` skips them). Seeds (`trainer.zoo`'s offsets), keys and the retry
rule mirror `trainer.zoo`'s loops; the Ray tests compare the two registries.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, cast

from sqlalchemy.engine import URL

from model_store.defaults import open_store
from model_store.store import ModelStore
from trainer.config import GATE_RETRIES, ImpactConfig, JointConfig, SoftQConfig, TaskConfig
from trainer.domain import Kind, TrainedBatch
from trainer.learners import chunked, combos_by_size, train_impacts, train_joint, train_tasks
from trainer.loop import TrainingCurves
from trainer.zoo import (
    IMPACT_SEED_OFFSET,
    JOINT_SEED_OFFSET,
    RETRY_SEED_STEP,
    goals_without,
    load_partner_nets,
    load_task_nets,
    production_parents_required,
    retry_batches,
    warn_unserved_parents,
)

from .once import RegisteredHook, publish_once


@dataclass(frozen=True)
class BatchJob:
    """One batch: members are `(goal,)` for task/impact, `(ego, partner, ...)` for joint."""

    kind: Kind
    members: tuple[tuple[str, ...], ...]
    seed: int
    index: int  # position in its stage (orders the summary)
    key: str  # what `RunState` records for it (the same as the local loops')


@dataclass(frozen=True)
class Stage:
    """Jobs that may run at the same time, with their shared config. A task or impact stage
    with `gate_retries` then trains the goals that failed their gate again, one attempt at a
    time."""

    jobs: tuple[BatchJob, ...]
    config: SoftQConfig
    gate_retries: int = 0
    goals: tuple[str, ...] = ()
    seed: int = 0


def _members(goals: Sequence[str]) -> tuple[tuple[str, ...], ...]:
    return tuple((g,) for g in goals)


def task_stage(
    goals: Sequence[str],
    config: TaskConfig,
    *,
    seed: int,
    per_batch: int,
    gate_retries: int = GATE_RETRIES,
) -> Stage:
    jobs = [
        BatchJob("task", _members(chunk), seed + i, i, f"task:{','.join(chunk)}")
        for i, chunk in enumerate(chunked(goals, per_batch))
    ]
    return Stage(tuple(jobs), config, gate_retries, tuple(goals), seed)


def retry_jobs(stage: Stage, attempt: int, failed: Sequence[str]) -> list[BatchJob]:
    """Attempt `attempt` (1, 2 ...) at the goals of a task or impact `stage` whose network
    failed its gate, as two batches of candidates (the seeds and keys of `trainer.zoo.run_tasks` /
    `run_impacts`, `trainer.zoo.retry_batches`)."""
    kind = stage.jobs[0].kind
    offset = IMPACT_SEED_OFFSET if kind == "impact" else 0
    seed = stage.seed + offset + RETRY_SEED_STEP * attempt  # a fresh seed per attempt
    index = len(stage.jobs) + 2 * (attempt - 1)
    return [
        BatchJob(kind, _members(goals), seed + i, index + i, f"{kind}-retry-{attempt}:{i}")
        for i, goals in enumerate(retry_batches(failed))
    ]


def impact_stage(
    goals: Sequence[str],
    config: ImpactConfig,
    *,
    seed: int,
    per_batch: int,
    gate_retries: int = GATE_RETRIES,
) -> Stage:
    chunks = chunked(goals, per_batch)
    seeds = [seed + IMPACT_SEED_OFFSET + i for i in range(len(chunks))]
    jobs = [
        BatchJob("impact", _members(chunk), seeds[i], i, f"impact:{','.join(chunk)}")
        for i, chunk in enumerate(chunks)
    ]
    return Stage(tuple(jobs), config, gate_retries, tuple(goals), seed)


def impact_jobs_with_parents(
    store: ModelStore, env: str, jobs: Sequence[BatchJob]
) -> tuple[BatchJob, ...]:
    """The impact `jobs` that may run now: in the kitchen, without the goals whose task network
    has no `production` version (skipped with a warning, as `trainer.zoo.run_impacts` does);
    elsewhere all of them (a `latest` parent is allowed)."""
    if not production_parents_required(env):
        return tuple(jobs)
    goals = [m[0] for job in jobs for m in job.members]
    unserved = goals_without(store, env, "task", goals, "production")
    if unserved:
        warn_unserved_parents(unserved, env)
    return without_goals(jobs, unserved)


def without_goals(jobs: Sequence[BatchJob], skipped: Sequence[str]) -> tuple[BatchJob, ...]:
    """Impact `jobs` minus the `skipped` goals, as `trainer.zoo.run_impacts` skips a goal whose
    task network has no `production` version in the kitchen: a job keeps its seed and index,
    its key names the goals left (the local loop's key), and a job left empty is dropped."""
    kept = []
    for job in jobs:
        members = tuple(m for m in job.members if m[0] not in skipped)
        if members == job.members:
            kept.append(job)
        elif members:
            key = f"{job.kind}:{','.join(m[0] for m in members)}"
            kept.append(BatchJob(job.kind, members, job.seed, job.index, key))
    return tuple(kept)


def joint_stage(combos: Sequence[Sequence[str]], config: JointConfig, *, seed: int) -> Stage:
    """Combinations with the same number of agents train together (as `run_joint`)."""
    jobs = []
    for i, (size, group) in enumerate(combos_by_size(combos)):
        key = "joint:" + ";".join("+".join(c) for c in group)
        jobs.append(BatchJob("joint", tuple(group), seed + JOINT_SEED_OFFSET + size, i, key))
    return Stage(tuple(jobs), config)


@dataclass
class BatchOutcome:
    """What a finished job reports back: enough for `trainer.report`, no weights."""

    kind: Kind
    goals: list[tuple[str, ...]]
    config: SoftQConfig
    seed: int
    curves: TrainingCurves
    gates: list[Any] = field(default_factory=list)  # as `TrainedBatch.gates` (per world)
    versions: list[str] = field(default_factory=list)  # registered refs "name/version"

    def gate_passed(self, g: int) -> bool | None:
        gate = self.gates[g] if self.gates else None
        return None if gate is None else gate.passed

    def curve_summary(self, g: int) -> dict[str, Any]:
        return TrainedBatch.curve_summary(cast(Any, self), g)  # reads only `curves`


def train_batch(
    store_url: str | URL,
    job: BatchJob,
    config: SoftQConfig,
    *,
    job_key: str,
    env: str = "particle",
    serve_alias: str = "production",
    on_register: RegisteredHook | None = None,
) -> BatchOutcome:
    """Train `job` and register its networks once per `job_key` (module docstring)."""
    goals = [m[0] for m in job.members]
    with open_store(store_url, create=True) as store:
        parents: dict[tuple[str, ...], list[str]] = {}
        if job.kind == "task":
            batch = train_tasks(goals, cast(TaskConfig, config), seed=job.seed)
        elif job.kind == "impact":
            partner_nets, task_versions = load_task_nets(store, env, goals)
            parents = {(g,): [v.ref] for g, v in zip(goals, task_versions, strict=True)}
            batch = train_impacts(goals, partner_nets, cast(ImpactConfig, config), seed=job.seed)
        else:
            slot_nets, parents = load_partner_nets(store, env, job.members)
            ego_nets, _ = load_task_nets(store, env, [m[0] for m in job.members])
            batch = train_joint(
                job.members,
                slot_nets,
                cast(JointConfig, config),
                seed=job.seed,
                ego_task_nets=ego_nets,
            )
        registered = publish_once(
            store,
            store_url,
            batch,
            job_key=job_key,
            env=env,
            parents=parents,
            serve_alias=serve_alias if job.kind == "task" else "production",
            on_register=on_register,
        )
    return BatchOutcome(
        batch.kind,
        batch.goals,
        batch.config,
        batch.seed,
        batch.curves,
        list(batch.gates),
        [v.ref for v in registered],
    )
