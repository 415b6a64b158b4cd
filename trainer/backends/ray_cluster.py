"""Run batch jobs as Ray tasks: one task per batch, stage after stage.

    outcomes = run_on_ray(store_url, [task_stage(...), impact_stage(...)], run=run,
                          job_id=job_id_for(run_dir, resume), address="auto")

| choice             | value                                                                  |
|--------------------|------------------------------------------------------------------------|
| address            | None: `RAY_ADDRESS` if set, else a local Ray instance for this run;    |
|                    | `auto`: the cluster running on this machine; `ray://head:10001`: Ray   |
|                    | Client. A Ray session already open in this process is reused.          |
| resources per task | 1 CPU (`num_cpus=1`): as many tasks at once as the cluster has CPUs    |
| gate retries       | a task or impact stage then re-trains the goals that failed their gate,|
|                    | as `trainer.zoo`'s loops do (`Stage.gate_retries`, default 3)          |
| retries            | `max_retries` (default 3) when the worker dies (node lost, OOM kill,   |
|                    | `os._exit`) and on `StoreUnavailable`; other errors fail the run at    |
|                    | once and cancel the jobs still running                                 |
| idempotence        | every attempt registers through `publish_once` with the job key        |
|                    | `"{job_id}/{batch key}"`: a retry never adds a duplicate version       |
| run record         | the driver records each finished batch in the `RunState`, so `--resume`|
|                    | skips it; the job id is kept in `<run dir>/job-id` for resumed runs    |

Workers open the store by URL: PostgreSQL for a real cluster; a SQLite file works when every
worker sees the same file (a single machine). Each task gets it as a URL object, the database's
password inside, never rendered into a string (`portable_store_url`). Each worker must have
coexist installed (the trainer image of docker/ with the `ray` extra, or a Ray `runtime_env`).
Ray is imported only here, only when this backend is used.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from sqlalchemy.engine import URL

from model_store.defaults import open_store, store_factory
from model_store.errors import StoreUnavailable
from model_store.sql import SqlModelStore
from model_store.sql.engine import is_sqlite, normalise_url
from trainer.config import SoftQConfig
from trainer.zoo import RunState, goals_without

from .jobs import (
    BatchJob,
    BatchOutcome,
    Stage,
    impact_jobs_with_parents,
    retry_jobs,
    train_batch,
)
from .once import RegisteredHook

DEFAULT_MAX_RETRIES = 3
JOB_ID_FILE = "job-id"

# (description, total) -> advance(done, total): the CLI's rich progress factory
ProgressFactory = Callable[[str, int], Callable[[int, int], None]]


def job_id_for(run_dir: Path, resume: bool) -> str:
    """A new id per run; a resumed run keeps the id recorded in its run directory."""
    file = run_dir / JOB_ID_FILE
    if resume and file.exists():
        return file.read_text().strip()
    run_dir.mkdir(parents=True, exist_ok=True)
    job_id = uuid.uuid4().hex
    file.write_text(job_id + "\n")
    return job_id


def portable_store_url(store_url: str | URL, password: str | None = None) -> str | URL:
    """The store as a worker must open it: coexist's SQL store as a URL object, a SQLite path
    made absolute (workers' cwd differs) and `password` (what `ModelStore.reopen_url` leaves
    out: `reopen_password`) put back into it; a plugin backend's URL as given (its
    `reopen_url`, which any process can open).

    The object, not a string: a Ray task's arguments travel pickled, so the password goes to
    the workers inside it without ever being rendered into a URL string, and not through the
    task's `runtime_env`, whose environment variables Ray's dashboard and logs show."""
    if isinstance(store_url, str) and store_factory(store_url) is not SqlModelStore:
        return store_url
    url = normalise_url(store_url)
    if is_sqlite(url):
        url = url.set(database=str(Path(url.database or "").expanduser().absolute()))
    if password is not None:
        url = url.set(password=password)
    return url


def run_on_ray(
    store_url: str | URL,
    stages: Sequence[Stage],
    *,
    run: RunState,
    job_id: str,
    env: str = "particle",
    serve_alias: str = "production",
    address: str | None = None,
    max_retries: int = DEFAULT_MAX_RETRIES,
    progress: ProgressFactory | None = None,
    on_register: RegisteredHook | None = None,
    store_password: str | None = None,
) -> list[BatchOutcome]:
    """Run the stages' jobs on Ray, in stage order; outcomes in job order. `store_password`:
    the password `store_url` leaves out (`portable_store_url`)."""
    import ray

    url = portable_store_url(store_url, store_password)
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(address=address, include_dashboard=False, log_to_driver=True)
    options: dict[str, Any] = {
        "num_cpus": 1,
        "max_retries": max_retries,
        "retry_exceptions": [StoreUnavailable],  # a database blip; other errors are bugs
    }
    make_remote: Any = ray.remote(**options)  # (Ray's stubs cannot type keyword-only args)
    remote_train = make_remote(train_batch)

    def run_jobs(jobs: Sequence[BatchJob], config: SoftQConfig) -> list[BatchOutcome]:
        """Submit `jobs` at once; record each in `run` as it finishes; outcomes in job order."""
        steps = config.total_steps  # progress in env steps, advanced as whole batches finish
        label = f"ray: {len(jobs)} {jobs[0].kind} batch{'es' if len(jobs) > 1 else ''}"
        advance = progress(label, steps * len(jobs)) if progress else None
        pending: dict[Any, BatchJob] = {
            remote_train.remote(
                url,
                job,
                config,
                job_key=f"{job_id}/{job.key}",
                env=env,
                serve_alias=serve_alias,
                on_register=on_register,
            ): job
            for job in jobs
        }
        finished: list[tuple[int, BatchOutcome]] = []
        try:
            while pending:
                ready, _ = ray.wait(list(pending), num_returns=1)
                job = pending.pop(ready[0])
                outcome: BatchOutcome = ray.get(ready[0])
                run.done[job.key] = outcome.versions
                run.save()
                finished.append((job.index, outcome))
                if advance is not None:
                    advance(steps * len(finished), steps * len(jobs))
        except BaseException:
            for ref in pending:
                ray.cancel(ref)
            raise
        return [outcome for _, outcome in sorted(finished, key=lambda f: f[0])]

    outcomes: list[BatchOutcome] = []
    try:
        for stage in stages:
            jobs = stage.jobs
            if jobs and jobs[0].kind == "impact":
                with open_store(url, create=True) as store:
                    jobs = impact_jobs_with_parents(store, env, jobs)
            todo = [job for job in jobs if job.key not in run.done]
            if todo:
                outcomes += run_jobs(todo, stage.config)
            kind = stage.jobs[0].kind if stage.jobs else "task"
            trained = {m[0] for job in jobs for m in job.members}
            for attempt in range(1, stage.gate_retries + 1):  # as trainer.zoo's loops
                if f"{kind}-retry-{attempt}" in run.done:
                    continue
                with open_store(url, create=True) as store:
                    goals = [g for g in stage.goals if kind == "task" or g in trained]
                    alias = serve_alias if kind == "task" else "production"
                    failed = goals_without(store, env, kind, goals, alias)
                if failed:
                    retry = [j for j in retry_jobs(stage, attempt, failed) if j.key not in run.done]
                    outcomes += run_jobs(retry, stage.config) if retry else []
                    run.done[f"{kind}-retry-{attempt}"] = []  # its halves are recorded as they end
                    run.save()
    finally:
        if started_here:
            ray.shutdown()
    return outcomes
