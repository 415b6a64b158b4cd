"""The whole pipeline for an environment: task networks, then impact networks, then JL baselines.

Order matters: an impact network for partner goal h is trained against the *registered* task
network of h (its `production` version, else `latest`), and names that version as its parent.
Where the environment's trainer says so (`EnvTrainer.production_parents_only`: the kitchen) it
must be the `production` version: a goal whose task network failed every gate attempt gets no
impact network (`run_impacts` skips it with a warning, and a later `--resume` or `coexist train
impact` trains it once a task network has passed). The particle world keeps the fallback: its
quick tiny zoos (`--fast`, tests) serve networks that fail gates.
Work is done in batches of goals; a run directory records finished batches, so an interrupted
run resumes where it stopped (`--resume`) instead of starting again.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import torch

from model_store.entities import ModelVersion
from model_store.errors import NotFound
from model_store.naming import task_model_name
from model_store.store import ModelStore
from policy.qnet import QNetSpec, StackedQNet, tensors_from_safetensors
from trainer.config import GATE_RETRIES, SoftQConfig
from trainer.domain import env_trainer
from trainer.learners import TrainedBatch, chunked, train_impacts, train_joint, train_tasks
from trainer.loop import ProgressFactory
from trainer.parallel import BatchJob, train_batches
from trainer.publish import publish_batch

log = logging.getLogger(__name__)


def load_task_nets(
    store: ModelStore, env: str, goals: Sequence[str], alias: str = "production"
) -> tuple[StackedQNet, list[ModelVersion]]:
    """Stack the registered task networks of `goals` (alias, falling back to `latest`)."""
    versions = []
    for goal in goals:
        name = task_model_name(env, goal)
        try:
            versions.append(store.resolve(f"{name}@{alias}"))
        except NotFound:
            versions.append(store.resolve(f"{name}@latest"))
    specs = {json.dumps(v.spec, sort_keys=True) for v in versions}
    if len(specs) != 1:
        raise ValueError(f"task networks of {list(goals)} have different architectures")
    spec = QNetSpec.from_json(versions[0].spec)
    states = []
    for v in versions:
        tensors = tensors_from_safetensors(spec, store.load_weights(v.name, v.version))
        states.append({k: torch.from_numpy(a) for k, a in tensors.items()})
    return StackedQNet.from_members(spec, states), versions


@dataclass
class RunState:
    """What an interrupted run has finished (kept as JSON in its run directory)."""

    path: Path
    fingerprint: str
    done: dict[str, list[str]] = field(default_factory=dict)  # batch key -> version refs

    @classmethod
    def open(cls, run_dir: Path, fingerprint: str, resume: bool) -> RunState:
        file = run_dir / "run.json"
        if resume and file.exists():
            data = json.loads(file.read_text())
            if data["fingerprint"] != fingerprint:
                raise ValueError(
                    f"--resume: {run_dir} was started with other settings; start a new run"
                )
            return cls(file, fingerprint, data["done"])
        run_dir.mkdir(parents=True, exist_ok=True)
        state = cls(file, fingerprint)
        state.save()
        return state

    def save(self) -> None:
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(json.dumps({"fingerprint": self.fingerprint, "done": self.done}, indent=1))
        tmp.replace(self.path)  # atomic: a crash never leaves a half-written record

    def record(self, key: str, versions: list[ModelVersion]) -> None:
        self.done[key] = [f"{v.name}/{v.version}" for v in versions]
        self.save()


def fingerprint(**parts: object) -> str:
    blob = json.dumps(parts, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:16]


def check_config_env(config: SoftQConfig, env: str) -> None:
    """A configuration trains in the environment it names (`SoftQConfig.ENV`)."""
    if env != config.ENV:
        raise ValueError(f"config: a {type(config).__name__} does not train env {env!r}")


def run_tasks(
    store: ModelStore,
    goals: Sequence[str],
    config: SoftQConfig,
    *,
    seed: int,
    goals_per_batch: int,
    run: RunState,
    progress: ProgressFactory,
    env: str = "particle",
    serve_alias: str = "production",
    gate_retries: int = GATE_RETRIES,
    workers: int = 1,
) -> list[TrainedBatch]:
    """Task networks in batches; goals whose network failed its gate are trained again with a
    fresh seed, up to `gate_retries` times (each retry registers a new version). A goal without a
    `production` task network cannot be served as an ego, and in the particle world its impact
    network would learn beside a failed partner, so the zoo retries up to three times: in the
    second fresh zoo of 35 goals one goal (`d3`) failed its first two attempts. Up to `workers`
    batches train at once, in as many processes (`trainer.parallel`: the same networks)."""
    check_config_env(config, env)
    keys, jobs = [], []
    for i, chunk in enumerate(chunked(goals, goals_per_batch)):
        key = f"task:{','.join(chunk)}"
        if key not in run.done:
            keys.append(key)
            label = f"task {chunk[0]}..{chunk[-1]}"
            jobs.append(
                BatchJob(
                    label, config.total_steps, train_tasks, (chunk, config), {"seed": seed + i}
                )
            )
    batches = []
    for key, batch in zip(
        keys, train_batches(jobs, workers=workers, progress=progress), strict=True
    ):
        run.record(key, publish_batch(store, batch, env=env, serve_alias=serve_alias))
        batches.append(batch)
    for attempt in range(1, gate_retries + 1):
        key = f"task-retry-{attempt}"
        failed = goals_without(store, env, "task", goals, serve_alias)
        if key in run.done or not failed:
            continue
        retry_jobs = [
            BatchJob(
                retry_label("task", attempt, i, goals),
                config.total_steps,
                train_tasks,
                (goals, config),
                {"seed": seed + 7919 * attempt + i},  # a fresh seed per batch, deterministic
            )
            for i, goals in enumerate(retry_batches(failed))
        ]
        trained = train_batches(retry_jobs, workers=workers, progress=progress)
        for i, batch in enumerate(trained):
            versions = publish_batch(store, batch, env=env, serve_alias=serve_alias)
            run.record(f"{key}:{i}", versions)
            batches.append(batch)
        run.record(key, [])  # its batches' versions are recorded under their own keys
    return batches


def retry_batches(failed: Sequence[str]) -> list[list[str]]:
    """The batches of a gate retry: the failed goals in two halves (one batch per worker), each
    goal twice in its batch: two candidates per goal and attempt, with their own initial weights
    and experience, trained side by side. Why: a goal whose first network failed can fail again
    with the next seed (a fresh `make serve` once failed `e1`'s wall check on all four attempts
    of one candidate each), and a goal without a network is a goal the server cannot serve.
    Both candidates of a goal sit in one batch, so they register in member order on every
    backend (the second, when both pass, gets the alias). The batches depend on the failed
    goals alone, so the networks never depend on the number of workers."""
    if not failed:
        return []
    return [half + half for half in chunked(list(failed), (len(failed) + 1) // 2)]


def retry_label(kind: str, attempt: int, index: int, goals: Sequence[str]) -> str:
    """The progress label of a retry batch: its goals once each (the batch holds each twice)."""
    return (
        f"{kind} retry {attempt}.{index + 1}: {','.join(dict.fromkeys(goals))} (2 candidates each)"
    )


def run_impacts(
    store: ModelStore,
    goals: Sequence[str],
    config: SoftQConfig,
    *,
    seed: int,
    goals_per_batch: int,
    run: RunState,
    progress: ProgressFactory,
    env: str = "particle",
    production_parents_only: bool | None = None,
    gate_retries: int = GATE_RETRIES,
    workers: int = 1,
) -> list[TrainedBatch]:
    """Impact networks in batches, each against its partner goal's registered task network.
    `production_parents_only` (default: in the kitchen only, module docstring) skips goals whose
    task network has no `production` version instead of using `latest`. Goals whose network
    failed its gate are trained again with a fresh seed, up to `gate_retries` times, as
    `run_tasks` does; up to `workers` batches train at once."""
    check_config_env(config, env)
    strict = (
        production_parents_required(env)
        if production_parents_only is None
        else production_parents_only
    )
    unserved = goals_without(store, env, "task", goals, "production") if strict else []
    if unserved:
        warn_unserved_parents(unserved, env)
    trainable = [g for g in goals if g not in unserved]
    first = []
    for i, chunk in enumerate(chunked(goals, goals_per_batch)):
        kept = [g for g in chunk if g in trainable]
        key = f"impact:{','.join(kept)}"
        if kept and key not in run.done:
            first.append((kept, seed + 1000 + i, f"impact {kept[0]}..{kept[-1]}", key))
    batches = _impact_batches(
        store, first, config, run=run, progress=progress, env=env, workers=workers
    )
    for attempt in range(1, gate_retries + 1):
        key = f"impact-retry-{attempt}"
        failed = goals_without(store, env, "impact", trainable, "production")
        if key in run.done or not failed:
            continue
        retry_seed = seed + 1000 + 7919 * attempt  # a fresh seed per attempt, still deterministic
        retry = [
            (
                goals,
                retry_seed + i,
                retry_label("impact", attempt, i, goals),
                f"{key}:{i}",
            )
            for i, goals in enumerate(retry_batches(failed))
        ]
        batches += _impact_batches(
            store, retry, config, run=run, progress=progress, env=env, workers=workers
        )
        run.record(key, [])  # its batches' versions are recorded under their own keys
    return batches


def _impact_batches(
    store: ModelStore,
    chunks: Sequence[tuple[list[str], int, str, str]],
    config: SoftQConfig,
    *,
    run: RunState,
    progress: ProgressFactory,
    env: str,
    workers: int = 1,
) -> list[TrainedBatch]:
    """Train, gate and register the impact networks of each (goals, seed, label, run key)
    chunk, parented to the task networks they learned beside."""
    jobs: list[BatchJob] = []
    parents: list[dict[tuple[str, ...], list[str]]] = []
    for goals, seed, label, _key in chunks:
        partner_nets, task_versions = load_task_nets(store, env, goals)
        jobs.append(
            BatchJob(
                label,
                config.total_steps,
                train_impacts,
                (goals, partner_nets, config),
                {"seed": seed},
            )
        )
        parents.append(
            {(g,): [f"{v.name}/{v.version}"] for g, v in zip(goals, task_versions, strict=True)}
        )
    batches = []
    trained = train_batches(jobs, workers=workers, progress=progress)
    for (_goals, _seed, _label, key), parent, batch in zip(chunks, parents, trained, strict=True):
        run.record(key, publish_batch(store, batch, env=env, parents=parent))
        batches.append(batch)
    return batches


def run_joint(
    store: ModelStore,
    combos: Sequence[Sequence[str]],
    config: SoftQConfig,
    *,
    seed: int,
    run: RunState,
    progress: ProgressFactory,
    env: str = "particle",
) -> list[TrainedBatch]:
    """JL networks; combinations with the same number of agents train together."""
    batches = []
    by_size: dict[int, list[tuple[str, ...]]] = {}
    for combo in combos:
        by_size.setdefault(len(combo), []).append(tuple(combo))
    for size, group in sorted(by_size.items()):
        key = "joint:" + ";".join("+".join(c) for c in group)
        if key in run.done:
            continue
        partner_nets: list[StackedQNet] = []
        parents: dict[tuple[str, ...], list[str]] = {c: [] for c in group}
        for slot in range(1, size):
            nets, versions = load_task_nets(store, env, [c[slot] for c in group])
            partner_nets.append(nets)
            for c, v in zip(group, versions, strict=True):
                parents[c].append(f"{v.name}/{v.version}")
        batch = train_joint(
            group,
            partner_nets,
            config,
            seed=seed + 2000 + size,
            progress=progress(f"joint {size} agents", config.total_steps),
        )
        run.record(key, publish_batch(store, batch, env=env, parents=parents))
        batches.append(batch)
    return batches


def production_parents_required(env: str) -> bool:
    """Whether an impact network must be trained against a `production` task network (the
    kitchen: module docstring), or may fall back to `latest` (the particle world)."""
    return env_trainer(env).production_parents_only


def warn_unserved_parents(goals: Sequence[str], env: str) -> None:
    log.warning(
        "impact %s: skipped, the task network has no 'production' version (every gate "
        "attempt failed); train a passing one, then `coexist train impact --env %s`",
        ",".join(goals),
        env,
    )


def goals_without(
    store: ModelStore, env: str, kind: str, goals: Sequence[str], alias: str
) -> list[str]:
    """Goals whose `{env}/{kind}/{goal}` model has no version under `alias`."""
    from model_store.naming import impact_model_name

    name_of = task_model_name if kind == "task" else impact_model_name
    missing = []
    for goal in goals:
        try:
            store.resolve(f"{name_of(env, goal)}@{alias}")
        except NotFound:
            missing.append(goal)
    return missing
