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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal, TypeVar

import torch

from model_store.entities import ModelVersion
from model_store.errors import NotFound
from model_store.naming import task_model_name
from model_store.store import ModelStore
from policy.qnet import QNetSpec, StackedQNet, tensors_from_safetensors
from trainer.config import GATE_RETRIES, SoftQConfig
from trainer.learners import (
    TrainedBatch,
    chunked,
    combos_by_size,
    train_impacts,
    train_joint,
    train_tasks,
)
from trainer.loop import ProgressFactory
from trainer.parallel import BatchJob, train_batches
from trainer.plugins import env_trainer
from trainer.publish import publish_batch

log = logging.getLogger(__name__)

# The stages' seeds: tasks from `seed`, impacts from `seed + IMPACT_SEED_OFFSET`, joint networks
# of N agents `seed + JOINT_SEED_OFFSET + N`; gate retry `attempt` of a stage adds
# `RETRY_SEED_STEP x attempt` (the job backends use the same, `trainer.backends.jobs`).
IMPACT_SEED_OFFSET = 1000
Key = TypeVar("Key")
JOINT_SEED_OFFSET = 2000
RETRY_SEED_STEP = 7919


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


def load_partner_nets(
    store: ModelStore, env: str, combos: Sequence[tuple[str, ...]]
) -> tuple[list[StackedQNet], dict[tuple[str, ...], list[str]]]:
    """For (ego, partner, ...) combinations of one size: the registered task networks of each
    partner slot k = 1, 2, ... stacked over `combos` (as `train_joint` takes them), and each
    combination's parents (its partners' task networks, "name/version")."""
    slot_nets = []
    parents: dict[tuple[str, ...], list[str]] = {c: [] for c in combos}
    for slot in range(1, len(combos[0])):
        nets, versions = load_task_nets(store, env, [c[slot] for c in combos])
        slot_nets.append(nets)
        for c, v in zip(combos, versions, strict=True):
            parents[c].append(v.ref)
    return slot_nets, parents


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
    """A configuration trains in the environment it names (`SoftQConfig.env_name()`)."""
    if env != config.env_name():
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
    return _run_gated(
        store,
        "task",
        goals,
        [],
        config,
        seed=seed,
        goals_per_batch=goals_per_batch,
        gate_retries=gate_retries,
        workers=workers,
        run=run,
        progress=progress,
        env=env,
        serve_alias=serve_alias,
    )


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
    return _run_gated(
        store,
        "impact",
        goals,
        unserved,
        config,
        seed=seed + IMPACT_SEED_OFFSET,
        goals_per_batch=goals_per_batch,
        gate_retries=gate_retries,
        workers=workers,
        run=run,
        progress=progress,
        env=env,
        serve_alias="production",
    )


def _run_gated(
    store: ModelStore,
    kind: Literal["task", "impact"],
    goals: Sequence[str],
    skipped: Sequence[str],
    config: SoftQConfig,
    *,
    seed: int,
    goals_per_batch: int,
    gate_retries: int,
    workers: int,
    run: RunState,
    progress: ProgressFactory,
    env: str,
    serve_alias: str,
) -> list[TrainedBatch]:
    """The networks of `kind` for `goals` but the `skipped` ones, then the gate retries; the loop
    of `run_tasks` and `run_impacts`.

    Batch i of `goals` trains its goals left with seed `seed + i` under the run key
    `{kind}:{goals}`; retry `attempt` trains the goals without a `serve_alias` version
    (`retry_batches`) with seeds `seed + RETRY_SEED_STEP x attempt + i` under
    `{kind}-retry-{attempt}:{i}`. Each batch is registered as soon as it is trained (an impact
    network names the task network it learned beside as its parent)."""

    def train(chunks: list[tuple[list[str], int, str, str]]) -> list[TrainedBatch]:
        """Train and register each (goals, seed, progress label, run key) chunk."""
        jobs, parents = [], []
        for chunk, chunk_seed, label, _key in chunks:
            learner: Callable[..., TrainedBatch] = train_tasks
            args: tuple[object, ...] = (chunk, config)
            parent: dict[tuple[str, ...], list[str]] | None = None
            if kind == "impact":
                partner_nets, task_versions = load_task_nets(store, env, chunk)
                learner, args = train_impacts, (chunk, partner_nets, config)
                parent = {(g,): [v.ref] for g, v in zip(chunk, task_versions, strict=True)}
            jobs.append(BatchJob(label, config.total_steps, learner, args, {"seed": chunk_seed}))
            parents.append(parent)
        batches = []
        trained = train_batches(jobs, workers=workers, progress=progress)
        for (*_, key), parent, batch in zip(chunks, parents, trained, strict=True):
            versions = publish_batch(store, batch, env=env, parents=parent, serve_alias=serve_alias)
            run.record(key, versions)
            batches.append(batch)
        return batches

    first = []
    for i, chunk in enumerate(chunked(goals, goals_per_batch)):
        kept = [g for g in chunk if g not in skipped]
        key = f"{kind}:{','.join(kept)}"
        if kept and key not in run.done:
            first.append((kept, seed + i, f"{kind} {kept[0]}..{kept[-1]}", key))
    batches = train(first)
    trainable = [g for g in goals if g not in skipped]
    for attempt in range(1, gate_retries + 1):
        key = f"{kind}-retry-{attempt}"
        failed = goals_without(store, env, kind, trainable, serve_alias)
        if key in run.done or not failed:
            continue
        retry_seed = seed + RETRY_SEED_STEP * attempt  # a fresh seed per attempt, deterministic
        batches += train(
            [
                (chunk, retry_seed + i, retry_label(kind, attempt, i, chunk), f"{key}:{i}")
                for i, chunk in enumerate(retry_batches(failed))
            ]
        )
        run.record(key, [])  # its batches' versions are recorded under their own keys
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
    gate_retries: int = GATE_RETRIES,
) -> list[TrainedBatch]:
    """JL networks; combinations with the same number of agents train together, each gated
    against its ego's task network. The combinations that failed train again, alone of their
    size, with a fresh seed and twice the steps of their last attempt, up to `gate_retries`
    times (`JointConfig`); each attempt registers its networks, `production` only where
    passed."""
    batches = []
    for size, group in combos_by_size(combos):
        left, steps = list(group), config.total_steps
        for attempt in range(gate_retries + 1):
            name = "joint" if attempt == 0 else f"joint-retry-{attempt}"
            key = f"{name}:" + ";".join("+".join(c) for c in left)
            if key in run.done:  # resumed: this attempt was trained and registered
                left = joint_without(store, env, left, "production")
                if not left:
                    break
                steps *= 2
                continue
            partner_nets, parents = load_partner_nets(store, env, left)
            ego_nets, _ = load_task_nets(store, env, [c[0] for c in left])
            attempt_config = replace(config, total_steps=steps)
            batch = train_joint(
                left,
                partner_nets,
                attempt_config,
                seed=seed + JOINT_SEED_OFFSET + size + RETRY_SEED_STEP * attempt,
                progress=progress(f"{name} {size} agents", steps),
                ego_task_nets=ego_nets,
            )
            run.record(key, publish_batch(store, batch, env=env, parents=parents))
            batches.append(batch)
            left = [c for g, c in enumerate(left) if batch.gate_passed(g) is False]
            if not left:
                break
            steps *= 2
    return batches


def joint_without(
    store: ModelStore, env: str, combos: Sequence[tuple[str, ...]], alias: str
) -> list[tuple[str, ...]]:
    """Combinations whose joint network has no version under `alias`."""
    from model_store.naming import joint_model_name

    names = [(c, joint_model_name(env, c[0], c[1:])) for c in combos]
    return _without_alias(store, names, alias)


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
    return _without_alias(store, [(g, name_of(env, g)) for g in goals], alias)


def _without_alias(store: ModelStore, named: Sequence[tuple[Key, str]], alias: str) -> list[Key]:
    """The keys of the (key, model name) pairs whose model has no version under `alias`."""
    missing = []
    for key, name in named:
        try:
            store.resolve(f"{name}@{alias}")
        except NotFound:
            missing.append(key)
    return missing
