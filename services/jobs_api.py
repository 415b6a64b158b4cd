"""The training job API: trigger `coexist train ...` remotely (`trainer.jobs`).

| method | path                 | auth  | answers                                                       |
|--------|----------------------|-------|---------------------------------------------------------------|
| POST   | `/v1/jobs`           | write | 202 and the job (`queued`); 422 naming a bad field (seed      |
|        |                      |       | 0..2^31-1, steps 1..10^6, no unknown fields)                  |
| GET    | `/v1/jobs`           | read  | `{jobs: [...]}`, newest first (`limit`, default 100)          |
| GET    | `/v1/jobs/{id}`      | read  | the job: kind, args, status, times, exit code                 |
| GET    | `/v1/jobs/{id}/logs` | read  | `{id, status, log}`: the last `tail` characters; with         |
|        |                      |       | `offset`, the log from that byte on plus `next_offset`        |
| DELETE | `/v1/jobs/{id}`      | write | cancel: 200 `cancelled` (was queued), 202 `cancelling` (was   |
|        |                      |       | running; `cancelled` once its subprocess is gone); 409 naming |
|        |                      |       | the status of a finished job; 404 unknown id                  |

Jobs live in a SQL database (`training_jobs`): `COEXIST_JOBS_URL`, else the model store's own
database, else, for a store backend without SQL, the SQLite file `<data_dir>/jobs.db`; their run
directories and logs live under `<data_dir>/jobs/<id>`. A job's subprocess opens the model store
by its URL (`ModelStore.reopen_url`), whatever its backend: a plugin's is found by its scheme. The
runner thread starts with the app when unfinished jobs are waiting (a restarted server resumes
them, `--resume` skips finished batches) and otherwise on the first submit; it stops with the
app, leaving a running job for the next start. Jobs need a store another process can open.

One trainer per job: the trainer dies with the server process that started it, even on
`kill -9` (its parent-death signal), holds its run directory's lock while it lives, and a
restarted server stops any trainer of an earlier attempt still holding the directory before the
next attempt starts (`trainer.jobs.leash`); a runner that cannot renew its job's lease within
`COEXIST_JOB_LEASE_S` stops its trainer before another server takes the job over.

Cancelling a running job stops its `coexist train` subprocess (SIGTERM, SIGKILL after the
runner's grace period), from whichever server process answers the DELETE (`trainer.jobs.table`).
Networks the job registered before that stay in the store as complete versions (each is one
transaction); a cancelled job is never resumed. Submitting it again starts a new job with a new
run directory, so it trains from the first batch (`--resume` only spans restarts of one job).
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, FastAPI, Query, Request
from fastapi.responses import JSONResponse
from pydantic import Field
from sqlalchemy import URL

import services.registry  # noqa: F401  (first: importing services.deps first is a cycle)
from model_store.errors import InvalidArgument, StoreUnavailable
from model_store.sql.engine import normalise_url
from model_store.store import ModelStore

# isort: split
from services.deps import ReadAuth, WriteAuth
from services.rest.bounded import RequestBody
from services.rest.json_body import FastJsonRoute
from services.settings import Settings
from trainer.jobs import JobRunner, JobSpec, JobStatus, JobTable
from trainer.jobs.runner import append_log, read_log, read_log_from
from trainer.jobs.spec import MAX_SEED, MAX_STEPS, MAX_TEXT
from trainer.jobs.table import CANCELLED_WHILE_QUEUED

LOG_CHUNK_BYTES = 1 << 20  # the most one `offset` read of a log returns
JOBS_DATABASE = "jobs.db"  # the job table's file in the data directory, for a store without SQL


class JobRequest(RequestBody):
    """A job to run (`trainer.jobs.spec`); unknown fields are refused, as on every route."""

    kind: Literal["task", "impact", "joint", "zoo"]
    env: str = Field(default="particle", max_length=64)
    goals: str = Field(
        default="all", max_length=MAX_TEXT, description="'all' or comma-separated goal ids"
    )
    combos: str = Field(
        default="", max_length=MAX_TEXT, description="JL combinations: 'a2+b3,c+c4'"
    )
    seed: int = Field(default=0, ge=0, le=MAX_SEED)
    steps: int | None = Field(
        default=None,
        ge=1,
        le=MAX_STEPS,
        description="batched environment steps per batch of goals (default: the config's)",
    )


def _store_urls(app: FastAPI) -> tuple[URL, str, str | None]:
    """The job table's database URL (`_jobs_database`); the URL a job's subprocess opens the
    store by (`ModelStore.reopen_url`: a plugin's scheme stays a plugin's scheme), without the
    password; and the password apart (`reopen_password`). The last two go only into the
    trainer's environment, in two variables (`JobRunner`), never onto a command line, into a
    log or into an answer."""
    store = getattr(app.state, "store", None)
    if store is None:
        raise StoreUnavailable("training jobs need a model store (and it is not open)")
    store_url = store.reopen_url()
    if store_url is None:
        raise StoreUnavailable("training jobs need a model store another process can open")
    return _jobs_database(app.state.settings, store), store_url, store.reopen_password()


def _jobs_database(settings: Settings, store: ModelStore) -> URL:
    """`COEXIST_JOBS_URL`, else the store's own SQL database, else the SQLite file `jobs.db` in
    the data directory (a backend without SQL), SQLite paths made absolute; kept a URL object
    so that its password is never rendered into a string here."""
    if settings.jobs_url is not None:
        try:
            url = normalise_url(settings.jobs_url.get_secret_value())
        except InvalidArgument as err:  # its message names the store's setting, not this one
            why = err.message.removeprefix("store_url: ")
            raise InvalidArgument(f"COEXIST_JOBS_URL: {why}", field="jobs_url") from None
    else:
        own = getattr(store, "url", None)  # a SQL store's (a plugin over SQL has one too)
        file = str(settings.data_dir / JOBS_DATABASE)
        url = own if isinstance(own, URL) else URL.create("sqlite", database=file)
    if url.get_backend_name() == "sqlite" and url.database:
        url = url.set(database=str(Path(url.database).absolute()))
    return url


def _open(app: FastAPI) -> tuple[JobTable, JobRunner]:
    jobs: tuple[JobTable, JobRunner] | None = getattr(app.state, "jobs", None)
    if jobs is None:
        table_url, store_url, password = _store_urls(app)
        lease_s = app.state.settings.job_lease_s
        table = JobTable(table_url, stale_after_s=lease_s)
        runner = JobRunner(
            table, store_url=store_url, store_password=password, heartbeat_s=lease_s / 6
        )
        jobs = table, runner
        app.state.jobs = jobs
    return jobs


@asynccontextmanager
async def _lifespan(app: FastAPI) -> AsyncIterator[None]:
    """Resume unfinished jobs at start-up; stop the runner (not the jobs) at shutdown. A table
    and runner given to the app before it started (`app.state.jobs`, as tests do) are the
    giver's: they are used, and left running."""
    given = getattr(app.state, "jobs", None)
    store = getattr(app.state, "store", None)
    if store is not None and store.reopen_url() is not None:
        table, runner = _open(app)
        if table.has_unfinished():
            runner.start()
    try:
        yield
    finally:
        jobs = getattr(app.state, "jobs", None)
        if jobs is not None and jobs is not given:
            jobs[1].stop()
            jobs[0].close()
            app.state.jobs = None


router = APIRouter(prefix="/v1/jobs", tags=["jobs"], lifespan=_lifespan, route_class=FastJsonRoute)


def _table(request: Request) -> JobTable:
    return _open(request.app)[0]


TableDep = Annotated[JobTable, Depends(_table)]


@router.post("", status_code=202)
def submit(body: JobRequest, request: Request, _auth: WriteAuth) -> JSONResponse:
    """Queue a training job; it runs when the jobs before it have finished."""
    spec = JobSpec(**body.model_dump()).validate()
    table, runner = _open(request.app)
    run_root = (request.app.state.settings.data_dir / "jobs").absolute()
    job = table.submit(spec, str(run_root))
    runner.start()
    runner.wake()
    return JSONResponse(job.to_json(), status_code=202)


@router.get("")
def list_jobs(
    table: TableDep, _auth: ReadAuth, limit: Annotated[int, Query(ge=1, le=1000)] = 100
) -> dict[str, Any]:
    return {"jobs": [job.to_json() for job in table.list_jobs(limit)]}


@router.get("/{job_id}")
def get_job(job_id: str, table: TableDep, _auth: ReadAuth) -> dict[str, Any]:
    return table.get(job_id).to_json()


@router.delete("/{job_id}")
def cancel_job(job_id: str, request: Request, _auth: WriteAuth) -> JSONResponse:
    """Cancel a queued job at once, or have the runner of a running one stop its subprocess."""
    table, runner = _open(request.app)
    job = table.cancel(job_id)
    if job.status is JobStatus.cancelled:
        append_log(job.run_dir, CANCELLED_WHILE_QUEUED)  # a requeued job already has a log
        return JSONResponse(job.to_json(), status_code=200)
    runner.wake()  # when this process runs the job, it stops it now rather than at its next poll
    return JSONResponse(job.to_json(), status_code=202)


@router.get("/{job_id}/logs")
def get_logs(
    job_id: str,
    table: TableDep,
    _auth: ReadAuth,
    tail: Annotated[int, Query(ge=1, le=1_000_000)] = 64_000,
    offset: Annotated[
        int | None,
        Query(ge=0, le=2**63 - 1, description="byte offset to read from (to follow a log)"),
    ] = None,
) -> dict[str, Any]:
    """The log file when this machine has it, else the tail the row kept when the job ended."""
    job = table.get(job_id)
    if offset is None:
        text = read_log(job.run_dir, tail) or job.log_tail[-tail:]
        return {"id": job.id, "status": job.status.value, "log": text}
    chunk = read_log_from(job.run_dir, offset, LOG_CHUNK_BYTES)
    if chunk is None:  # no log file here: follow the row's tail as if it were the file
        kept = job.log_tail.encode()[offset : offset + LOG_CHUNK_BYTES]
        chunk = kept.decode("utf-8", errors="replace"), offset + len(kept)
    text, next_offset = chunk
    return {"id": job.id, "status": job.status.value, "log": text, "next_offset": next_offset}
