"""`coexist train ...`: train task, impact and joint-learner networks and register them.

    coexist train task   --env particle --goals all|a3,b,... [--seed 0] [--steps N]
    coexist train impact --env particle --goals all|...
    coexist train joint  --env particle --combos a2+b3,c+c4
    coexist train zoo    --env particle            # tasks, then impacts (and --combos for JL)
    coexist train zoo    --env cooking --goals TomatoLettuceSalad,CarrotBanana
    coexist train task   --env cooking --goals CarrotBanana --seed 1 --alias partners

Every command shows a progress bar per batch of goals, prints a summary table at the end and
registers each network (with `latest`, plus `production` when its quality gate passes).
`--run-dir` keeps the record of finished batches: rerun with `--resume` after an interruption.

`--backend ray [--ray-address auto|ray://host:port]` runs every batch as a Ray task instead (task
batches first, then the impact and joint batches that need them); each task registers its
networks itself, once, even when Ray retries it (`trainer.backends`). Use a PostgreSQL
`--store-url` that every node reaches. The default `--backend local` never imports Ray.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer

app = typer.Typer(help="Train task, impact and joint-learner networks.", no_args_is_help=True)

EnvOpt = Annotated[str, typer.Option(help="Environment name.")]
GoalsOpt = Annotated[str, typer.Option(help="'all' or comma-separated goal ids (a3, b, 4 ...).")]
SeedOpt = Annotated[int, typer.Option(help="Seed of networks, rollouts and gates.")]
StepsOpt = Annotated[
    int | None, typer.Option(help="Batched env steps per batch (default: config).")
]
BatchOpt = Annotated[int, typer.Option(help="Goals trained together in one batch.")]
WorkersOpt = Annotated[
    int,
    typer.Option(min=1, help="Batches trained at once, one process each (the same networks as 1)."),
]
StoreOpt = Annotated[
    str | None,
    typer.Option(
        help="Model store URL (default: COEXIST_STORE_URL, else embedded SQLite). A URL with "
        "a password belongs in COEXIST_STORE_URL: every user of the machine sees a command line."
    ),
]
RunDirOpt = Annotated[Path, typer.Option(help="Where the run's record and plots go.")]
ResumeOpt = Annotated[bool, typer.Option(help="Skip batches this run directory already finished.")]
CombosOpt = Annotated[
    str, typer.Option(help="JL combinations: ego+partner[+partner...], comma-separated.")
]


class Backend(StrEnum):
    local = "local"
    ray = "ray"


BackendOpt = Annotated[
    Backend, typer.Option(help="local: this process; ray: one Ray task per batch of goals.")
]
RayAddressOpt = Annotated[
    str | None,
    typer.Option(
        help="Ray cluster: 'auto', 'ray://host:10001' (default: RAY_ADDRESS, else a local one)."
    ),
]


def _goals(env: str, goals: str) -> list[str]:
    from envs.base import check_goal
    from envs.registry import get_domain

    try:
        domain = get_domain(env)
    except ValueError as err:
        raise typer.BadParameter(str(err), param_hint="--env") from None
    if goals == "all":
        return list(domain.goals)
    chosen = [g.strip() for g in goals.split(",") if g.strip()]
    try:
        for g in chosen:
            check_goal(domain, g, "--goals")
    except ValueError as err:
        raise typer.BadParameter(str(err), param_hint="--goals") from None
    if not chosen:
        raise typer.BadParameter("expected 'all' or at least one goal id", param_hint="--goals")
    return chosen


def _combos(env: str, combos: str) -> list[list[str]]:
    from trainer.plugins import env_trainer

    no_joint = env_trainer(env).no_joint_reason
    if no_joint:
        raise typer.BadParameter(no_joint, param_hint="--combos")
    out = [_goals(env, ",".join(c.split("+"))) for c in combos.split(",") if c.strip()]
    for combo in out:
        if not 2 <= len(combo) <= 5:
            raise typer.BadParameter(
                f"{'+'.join(combo)}: expected 2 to 5 goals", param_hint="--combos"
            )
    return out


PROGRESS_LINES = 20  # outside a terminal: a line every 5 % of a batch


def _progress_lines(description: str, total: int) -> Any:
    """`advance(done, total)` printing `<description>: <done>/<total> steps` every 5 %."""
    every = max(1, total // PROGRESS_LINES)

    def advance(done: int, _total: int) -> None:
        if done % every == 0 or done == _total:
            print(f"{description}: {done}/{_total} steps", flush=True)

    return advance


@contextmanager
def progress_bars() -> Iterator[Any]:
    """A rich progress display; yields a factory `(description, total) -> advance(done, total)`.

    Outside a terminal (a training job's log, `trainer.jobs`) rich would print the bars only
    when they finish, so plain lines `<description>: <done>/<total> steps` come instead, every
    5 % of a batch: the log then says how far a job is (the web console draws them as a bar)."""
    from rich.console import Console

    if not Console().is_terminal:
        yield _progress_lines
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = (
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    with Progress(*columns, transient=False) as bars:

        def progress(description: str, total: int) -> Any:
            task_id = bars.add_task(description, total=total)

            def advance(done: int, _total: int) -> None:
                if done % 25 == 0 or done == _total:
                    bars.update(task_id, completed=done)

            return advance

        yield progress


@contextmanager
def _session(
    store_url: str | None, run_dir: Path, resume: bool, **fingerprint: Any
) -> Iterator[Any]:
    """Open the store, the run record and a rich progress display for one command."""
    from model_store.defaults import open_store
    from trainer.zoo import RunState
    from trainer.zoo import fingerprint as make_fingerprint

    store = open_store(store_url, create=True)  # training writes: a new store is asked for
    try:
        run = RunState.open(run_dir, make_fingerprint(**fingerprint), resume)
    except ValueError as err:
        store.close()
        raise typer.BadParameter(str(err), param_hint="--resume") from None
    try:
        with progress_bars() as progress:
            yield store, run, progress
    finally:
        store.close()


def _on_ray(
    store: Any,
    run: Any,
    progress: Any,
    stages: list[Any],
    *,
    run_dir: Path,
    resume: bool,
    env: str,
    address: str | None,
    serve_alias: str = "production",
) -> list[Any]:
    """Run `stages` as Ray tasks (`trainer.backends`); outcomes for the summary and plots."""
    from importlib.util import find_spec

    if find_spec("ray") is None:
        raise typer.BadParameter(
            "Ray is not installed: pip install 'coexist[ray]'", param_hint="--backend"
        )
    from trainer.backends.ray_cluster import job_id_for, run_on_ray

    sql_url = getattr(store, "url", None)  # a plugin's backend may have none
    if address and sql_url is not None and sql_url.get_backend_name() == "sqlite":
        typer.echo(
            "warning: the store is a SQLite file, which Ray workers on other machines cannot "
            "reach: use a PostgreSQL --store-url for a cluster",
            err=True,
        )
    worker_url = store.reopen_url()  # how the workers open the same store
    if worker_url is None:
        raise typer.BadParameter(
            f"{store!r} cannot be opened by another process: Ray workers need one that can",
            param_hint="--store-url",
        )
    return run_on_ray(
        worker_url,
        stages,
        run=run,
        job_id=job_id_for(run_dir, resume),
        env=env,
        serve_alias=serve_alias,
        address=address,
        progress=progress,
        store_password=store.reopen_password(),  # apart from the URL string, as to a job
    )


def _exit_if_a_gate_failed(batches: list[Any]) -> None:
    """Exit with `GATE_FAILED_EXIT_CODE` when a network's last gate (after the retries, which
    come later in `batches`) failed, printing that gate's figures: a run whose networks are
    registered but not fit to serve must not look like a success (a job ends `gate_failed`)."""
    from trainer.jobs.spec import GATE_FAILED_EXIT_CODE

    last: dict[tuple[str, tuple[str, ...]], Any] = {}
    for batch in batches:
        for g, goals in enumerate(batch.goals):
            gate = batch.gates[g] if batch.gates else None
            if gate is not None:
                last[(batch.kind, tuple(goals))] = gate
    failed = [(key, gate) for key, gate in last.items() if not gate.passed]
    if not failed:
        return
    for (kind, goals), gate in failed:
        figures = ", ".join(
            f"{name}={_figure(value)}"
            for name, value in gate.metrics().items()
            if name not in ("goal", "passed")
        )
        typer.echo(f"gate failed: {kind} {'+'.join(goals)}: {figures}")
    typer.echo(
        f"{len(failed)} network(s) failed their gate: registered as 'latest' only, not served "
        f"(exit code {GATE_FAILED_EXIT_CODE})"
    )
    raise typer.Exit(GATE_FAILED_EXIT_CODE)


def _figure(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _print_gates(env: str, batches: list[Any]) -> None:
    """The environment's gate details beyond the summary table (the kitchen's dish table)."""
    from trainer.plugins import env_trainer

    env_trainer(env).print_gates(batches)


def _configs(steps: int | None, env: str = "particle") -> tuple[Any, Any, Any]:
    """Task, impact and joint configurations of `env` (the kitchen has its own: sparse dishes)."""
    from trainer.config import JointConfig
    from trainer.plugins import env_trainer

    task, impact = env_trainer(env).default_configs()
    joint = JointConfig()
    if steps is not None:
        task = replace(task, total_steps=steps)
        impact = replace(impact, total_steps=steps)
        joint = replace(joint, total_steps=steps)
    return task, impact, joint


@app.command("task")
def task(
    env: EnvOpt = "particle",
    goals: GoalsOpt = "all",
    seed: SeedOpt = 0,
    steps: StepsOpt = None,
    goals_per_batch: BatchOpt = 35,
    workers: WorkersOpt = 1,
    store_url: StoreOpt = None,
    run_dir: RunDirOpt = Path("runs/task"),
    resume: ResumeOpt = False,
    alias: Annotated[
        str, typer.Option(help="Alias for networks that pass their gate (e.g. 'partners').")
    ] = "production",
    backend: BackendOpt = Backend.local,
    ray_address: RayAddressOpt = None,
) -> None:
    """Train one task network per goal (paper §3.1)."""
    from trainer.report import print_summary, write_curves
    from trainer.zoo import run_tasks

    goal_ids = _goals(env, goals)
    config, _, _ = _configs(steps, env)
    with _session(
        store_url,
        run_dir,
        resume,
        kind="task",
        goals=goal_ids,
        seed=seed,
        config=config,
        alias=alias,
    ) as (store, run, progress):
        if backend is Backend.ray:
            from trainer.backends.jobs import task_stage

            stage = task_stage(goal_ids, config, seed=seed, per_batch=goals_per_batch)
            batches = _on_ray(
                store,
                run,
                progress,
                [stage],
                run_dir=run_dir,
                resume=resume,
                env=env,
                address=ray_address,
                serve_alias=alias,
            )
        else:
            batches = run_tasks(
                store,
                goal_ids,
                config,
                seed=seed,
                goals_per_batch=goals_per_batch,
                run=run,
                progress=progress,
                env=env,
                serve_alias=alias,
                workers=workers,
            )
    print_summary(batches)
    _print_gates(env, batches)
    _exit_if_a_gate_failed(batches)
    write_curves(batches, run_dir)


@app.command("monitor")
def monitor(
    env: EnvOpt = "particle",
    goals: GoalsOpt = "all",
    seed: SeedOpt = 0,
    steps: Annotated[
        int | None, typer.Option(min=1, help="Adam steps, each on fresh states (default: 6000).")
    ] = None,
    store_url: StoreOpt = None,
    alias: Annotated[
        str, typer.Option(help="Alias for monitors that pass their gate.")
    ] = "production",
) -> None:
    """Train one goal monitor per goal: which actions keep a reached goal, so that AAIL-B asks
    the environment nothing at execution (trainer/monitor.py)."""
    from envs.registry import env_plugin
    from model_store.defaults import open_store
    from trainer.monitor import MonitorConfig, publish_monitors, train_gated
    from trainer.plugins import env_trainer

    goal_ids = _goals(env, goals)
    states = getattr(env_trainer(env), "monitor_states", None)
    if states is None:
        raise typer.BadParameter(f"env {env!r} has no states for goal monitors", param_hint="--env")
    labels = getattr(env_trainer(env), "monitor_labels", None)
    config = MonitorConfig() if steps is None else MonitorConfig(steps=steps)
    domain = env_plugin(env).domain
    with open_store(store_url, create=True) as store, progress_bars() as progress:
        attempts = train_gated(domain, states, goal_ids, config, seed, progress, labels)
        for trained in attempts:
            publish_monitors(store, trained, env=env, alias=alias)
    last = {
        g: gate
        for trained in attempts
        for g, gate in zip(trained.goals, trained.gates, strict=True)
    }
    failed = [g for g in goal_ids if not last[g].passed]
    worst = max(gate.false_keeps for gate in last.values())
    print(
        f"{len(goal_ids) - len(failed)} of {len(goal_ids)} monitors passed their gate (false "
        f"keeps at most {config.max_false_keeps:.0%}; the worst {worst:.2%}; "
        f"{len(attempts) - 1} retries)"
    )
    if failed:
        print(f"failed (registered as latest only): {', '.join(failed)}")
        raise typer.Exit(1)


@app.command("impact")
def impact(
    env: EnvOpt = "particle",
    goals: GoalsOpt = "all",
    seed: SeedOpt = 0,
    steps: StepsOpt = None,
    goals_per_batch: BatchOpt = 35,
    workers: WorkersOpt = 1,
    store_url: StoreOpt = None,
    run_dir: RunDirOpt = Path("runs/impact"),
    resume: ResumeOpt = False,
    backend: BackendOpt = Backend.local,
    ray_address: RayAddressOpt = None,
) -> None:
    """Train one impact network per partner goal by self-play (paper §3.2); needs the task nets."""
    from trainer.report import print_summary, write_curves
    from trainer.zoo import run_impacts

    goal_ids = _goals(env, goals)
    _, config, _ = _configs(steps, env)
    with _session(
        store_url, run_dir, resume, kind="impact", goals=goal_ids, seed=seed, config=config
    ) as (store, run, progress):
        if backend is Backend.ray:
            from trainer.backends.jobs import impact_stage

            stage = impact_stage(goal_ids, config, seed=seed, per_batch=goals_per_batch)
            batches = _on_ray(
                store,
                run,
                progress,
                [stage],
                run_dir=run_dir,
                resume=resume,
                env=env,
                address=ray_address,
            )
        else:
            batches = run_impacts(
                store,
                goal_ids,
                config,
                seed=seed,
                goals_per_batch=goals_per_batch,
                run=run,
                progress=progress,
                env=env,
                workers=workers,
            )
    print_summary(batches)
    _print_gates(env, batches)
    _exit_if_a_gate_failed(batches)
    write_curves(batches, run_dir)


@app.command("joint")
def joint(
    env: EnvOpt = "particle",
    combos: CombosOpt = "a2+b3,c+c4",
    seed: SeedOpt = 0,
    steps: StepsOpt = None,
    store_url: StoreOpt = None,
    run_dir: RunDirOpt = Path("runs/joint"),
    resume: ResumeOpt = False,
    backend: BackendOpt = Backend.local,
    ray_address: RayAddressOpt = None,
) -> None:
    """Train joint-learner (JL) baselines, one per goal combination; needs the task nets."""
    from trainer.report import print_summary, write_curves
    from trainer.zoo import run_joint

    combo_ids = _combos(env, combos)
    _, _, config = _configs(steps, env)
    with _session(
        store_url, run_dir, resume, kind="joint", combos=combo_ids, seed=seed, config=config
    ) as (store, run, progress):
        if backend is Backend.ray:
            from trainer.backends.jobs import joint_stage

            stage = joint_stage(combo_ids, config, seed=seed)
            batches = _on_ray(
                store,
                run,
                progress,
                [stage],
                run_dir=run_dir,
                resume=resume,
                env=env,
                address=ray_address,
            )
        else:
            batches = run_joint(
                store, combo_ids, config, seed=seed, run=run, progress=progress, env=env
            )
    print_summary(batches)
    _print_gates(env, batches)
    _exit_if_a_gate_failed(batches)
    write_curves(batches, run_dir)


@app.command("zoo")
def zoo(
    env: EnvOpt = "particle",
    goals: GoalsOpt = "all",
    combos: CombosOpt = "",
    seed: SeedOpt = 0,
    steps: StepsOpt = None,
    goals_per_batch: BatchOpt = 35,
    workers: WorkersOpt = 1,
    store_url: StoreOpt = None,
    run_dir: RunDirOpt = Path("runs/zoo"),
    resume: ResumeOpt = False,
    backend: BackendOpt = Backend.local,
    ray_address: RayAddressOpt = None,
) -> None:
    """The whole pipeline in order: task networks, impact networks, then JL combinations."""
    from trainer.report import print_summary, write_curves
    from trainer.zoo import run_impacts, run_joint, run_tasks

    goal_ids = _goals(env, goals)
    combo_ids = _combos(env, combos) if combos else []
    task_cfg, impact_cfg, joint_cfg = _configs(steps, env)
    fp = dict(
        kind="zoo",
        goals=goal_ids,
        combos=combo_ids,
        seed=seed,
        configs=[task_cfg, impact_cfg, joint_cfg],
    )
    with _session(store_url, run_dir, resume, **fp) as (store, run, progress):
        if backend is Backend.ray:
            from trainer.backends.jobs import impact_stage, joint_stage, task_stage

            per_batch = goals_per_batch
            stages = [
                task_stage(goal_ids, task_cfg, seed=seed, per_batch=per_batch),
                impact_stage(goal_ids, impact_cfg, seed=seed, per_batch=per_batch),
            ]
            if combo_ids:
                stages.append(joint_stage(combo_ids, joint_cfg, seed=seed))
            batches = _on_ray(
                store,
                run,
                progress,
                stages,
                run_dir=run_dir,
                resume=resume,
                env=env,
                address=ray_address,
            )
        else:
            common = dict(seed=seed, run=run, progress=progress, env=env)
            sizes: dict[str, Any] = dict(goals_per_batch=goals_per_batch, workers=workers)
            batches = run_tasks(store, goal_ids, task_cfg, **sizes, **common)
            batches += run_impacts(store, goal_ids, impact_cfg, **sizes, **common)
            if combo_ids:
                batches += run_joint(store, combo_ids, joint_cfg, **common)
    print_summary(batches)
    _print_gates(env, batches)
    _exit_if_a_gate_failed(batches)
    write_curves(batches, run_dir)
