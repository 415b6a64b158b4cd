"""The `training_jobs` table (migration 0002): the whole state of a job lives in its row.

| status        | meaning                                                                |
|---------------|------------------------------------------------------------------------|
| `queued`      | waiting for a runner (new, or recovered after its runner died)         |
| `running`     | a runner's subprocess trains it; `heartbeat_at` is refreshed meanwhile |
| `succeeded`   | the subprocess exited 0                                                |
| `failed`      | it exited non-zero (`exit_code`, `log_tail`)                           |
| `gate_failed` | it trained and registered, but a network failed its quality gate (even |
|               | after the retries): exit code `GATE_FAILED_EXIT_CODE`; the gate's      |
|               | figures are in its log                                                 |
| `interrupted` | its runner died `max_attempts` times while it ran: not retried again   |
| `cancelling`  | cancel asked while it ran: its runner is stopping the subprocess       |
| `cancelled`   | cancelled before it started, or its subprocess was stopped (exit code) |

Claiming is one conditional UPDATE (`WHERE status = 'queued'`), so two server processes over one
database never run the same job. A `running` row whose heartbeat is older than `stale_after_s`
belongs to a dead process: `recover` puts it back in the queue (its run directory records the
finished batches, so the retry trains only what is left).

The heartbeat is a lease fenced by the attempt number: `heartbeat`, `finish`,
`finish_cancelled` and `release` given the runner's `attempt` change the row only while it is
still that attempt. A runner whose job was recovered and claimed again (it could not renew in
time) learns so from `heartbeat` returning False and stops its trainer
(`trainer.jobs.runner`); it can never record the outcome of an attempt that is not its own.

Cancelling goes through the row too, so it works whichever server process answers the request:
`cancel` turns `queued` into `cancelled` at once and `running` into `cancelling`; the runner that
owns the subprocess sees it at its next poll, stops the process and calls `finish_cancelled`. A
`cancelling` row whose runner died is finished by `recover` as `cancelled`, never requeued, so a
restarted server does not resume a job somebody cancelled.

Database failures (a read-only or full disk, a dropped database or table, a server that went
away) leave every method as `StoreUnavailable`, as the model store's do, so the jobs API answers
them with 503 like the registry, never with a driver's error.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from enum import StrEnum
from typing import Any

from sqlalchemy import URL, Engine, or_, select, update
from sqlalchemy.exc import DBAPIError
from sqlalchemy.orm import Session, sessionmaker

from model_store.errors import Conflict, NotFound, StoreUnavailable, brief
from model_store.sql.engine import BEGIN_MODE_OPTION, create_store_engine, redact_url
from model_store.sql.migrate import ensure_schema
from model_store.sql.orm import TrainingJobRow
from trainer.jobs.spec import GATE_FAILED_EXIT_CODE, JobSpec

LOG_TAIL_CHARS = 8_000  # what the row keeps of a finished job's log
_RUNNER_DIED = "\n--- cancelled; its runner died before it could report the exit code\n"
CANCELLED_WHILE_QUEUED = "--- cancelled while queued"


class JobStatus(StrEnum):
    queued = "queued"
    running = "running"
    succeeded = "succeeded"
    failed = "failed"
    gate_failed = "gate_failed"
    interrupted = "interrupted"
    cancelling = "cancelling"
    cancelled = "cancelled"


UNFINISHED = (JobStatus.queued.value, JobStatus.running.value, JobStatus.cancelling.value)


@dataclass(frozen=True)
class Job:
    id: str
    spec: JobSpec
    status: JobStatus
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    exit_code: int | None
    attempts: int
    run_dir: str
    log_tail: str

    def to_json(self) -> dict[str, Any]:
        def iso(t: datetime | None) -> str | None:
            return None if t is None else _aware(t).isoformat()

        return {
            "id": self.id,
            "kind": self.spec.kind,
            "args": self.spec.to_json(),
            "status": self.status.value,
            "created_at": iso(self.created_at),
            "started_at": iso(self.started_at),
            "finished_at": iso(self.finished_at),
            "exit_code": self.exit_code,
            "attempts": self.attempts,
            "run_dir": self.run_dir,
        }


def _check_id(job_id: str) -> None:
    """An id with NUL is no job's (ids are made here), and PostgreSQL cannot compare it."""
    if "\x00" in job_id:
        raise NotFound(f"job {brief(job_id)} not found", field="id")


class JobTable:
    """Rows of `training_jobs` in the database at `url` (the model store's)."""

    def __init__(
        self, url: str | URL, *, max_attempts: int = 3, stale_after_s: float = 30.0
    ) -> None:
        self.engine: Engine = create_store_engine(url)
        self._where = f"job table in {redact_url(url)} unavailable"
        with self._unavailable():
            ensure_schema(self.engine)
        self.max_attempts, self.stale_after_s = max_attempts, stale_after_s
        writer = self.engine.execution_options(**{BEGIN_MODE_OPTION: "IMMEDIATE"})
        self._readers = sessionmaker(self.engine, expire_on_commit=False)
        self._writers = sessionmaker(writer, expire_on_commit=False)

    def close(self) -> None:
        self.engine.dispose()

    @contextmanager
    def _unavailable(self) -> Iterator[None]:
        """Database errors as `StoreUnavailable` (module docstring)."""
        try:
            yield
        except DBAPIError as exc:  # the driver's first line says why (never the URL's password)
            text = str(exc.orig if exc.orig is not None else exc).strip()
            why = text.splitlines()[0][:300] if text else type(exc).__name__
            raise StoreUnavailable(f"{self._where}: {why}") from exc

    @contextmanager
    def _read(self) -> Iterator[Session]:
        """One read transaction."""
        with self._unavailable(), self._readers() as session, session.begin():
            yield session

    @contextmanager
    def _write(self) -> Iterator[Session]:
        """One write transaction (`BEGIN IMMEDIATE` on SQLite)."""
        with self._unavailable(), self._writers() as session, session.begin():
            yield session

    def submit(self, spec: JobSpec, run_root: str) -> Job:
        job_id = uuid.uuid4().hex
        row = TrainingJobRow(
            id=job_id,
            kind=spec.kind,
            args=spec.to_json(),
            status=JobStatus.queued.value,
            created_at=_now(),
            attempts=0,
            run_dir=f"{run_root}/{job_id}",
            log_tail="",
        )
        with self._write() as s:
            s.add(row)
        return self.get(job_id)

    def get(self, job_id: str) -> Job:
        _check_id(job_id)
        with self._read() as s:
            row = s.get(TrainingJobRow, job_id)
            if row is None:
                raise NotFound(f"job {brief(job_id)} not found")
            return _job(row)

    def has_unfinished(self) -> bool:
        query = select(TrainingJobRow.id).where(TrainingJobRow.status.in_(UNFINISHED)).limit(1)
        with self._read() as s:
            return s.scalar(query) is not None

    def list_jobs(self, limit: int = 100) -> list[Job]:
        query = select(TrainingJobRow).order_by(TrainingJobRow.created_at.desc()).limit(limit)
        with self._read() as s:
            return [_job(r) for r in s.scalars(query)]

    def claim_next(self) -> Job | None:
        """Mark the oldest queued job running (attempts + 1) and return it; None if none."""
        oldest = select(TrainingJobRow.id).where(TrainingJobRow.status == JobStatus.queued.value)
        with self._read() as s:  # a read first: an empty queue takes no write lock
            job_id = s.scalar(oldest.order_by(TrainingJobRow.created_at).limit(1))
        if job_id is None:
            return None
        with self._write() as s:
            now = _now()
            claimed = _set(
                s,
                job_id,
                JobStatus.queued,
                None,
                status=JobStatus.running.value,
                started_at=now,
                heartbeat_at=now,
                attempts=TrainingJobRow.attempts + 1,
            )
        return self.get(job_id) if claimed else None

    def heartbeat(self, job_id: str, attempt: int | None = None) -> bool:
        """Renew the lease of a running job; False when it is no longer running (as `attempt`,
        when given): cancelled meanwhile, or recovered and claimed again."""
        with self._write() as s:
            return _set(s, job_id, JobStatus.running, attempt, heartbeat_at=_now())

    def status(self, job_id: str) -> JobStatus:
        """The row's status alone (what the runner polls while a job runs)."""
        _check_id(job_id)
        with self._read() as s:
            status = s.scalar(select(TrainingJobRow.status).where(TrainingJobRow.id == job_id))
        if status is None:
            raise NotFound(f"job {brief(job_id)} not found", field="id")
        return JobStatus(status)

    def finish(
        self, job_id: str, exit_code: int, log_tail: str, attempt: int | None = None
    ) -> None:
        """The subprocess exited by itself. A cancel that came too late to stop it loses: the
        row records what the process did."""
        status = _finished_status(exit_code)
        with self._write() as s:
            for expected in (JobStatus.running, JobStatus.cancelling):
                if _set(
                    s,
                    job_id,
                    expected,
                    attempt,
                    status=status.value,
                    exit_code=exit_code,
                    finished_at=_now(),
                    log_tail=log_tail[-LOG_TAIL_CHARS:],
                ):
                    return

    def cancel(self, job_id: str) -> Job:
        """Cancel a queued job (done at once) or ask the runner of a running one to stop it.

        Asking again while it is `cancelling` changes nothing; a finished job is a `Conflict`.
        """
        _check_id(job_id)
        with self._write() as s:
            row = s.get(TrainingJobRow, job_id)
            if row is None:
                raise NotFound(f"job {brief(job_id)} not found", field="id")
            if row.status == JobStatus.queued.value:
                row.status, row.finished_at = JobStatus.cancelled.value, _now()
                row.log_tail = CANCELLED_WHILE_QUEUED + "\n"
            elif row.status == JobStatus.running.value:
                row.status = JobStatus.cancelling.value
            elif row.status != JobStatus.cancelling.value:
                raise Conflict(
                    f"job {job_id!r} is already {row.status}: only queued or running jobs can "
                    "be cancelled",
                    field="status",
                )
            return _job(row)

    def finish_cancelled(
        self, job_id: str, exit_code: int | None, log_tail: str, attempt: int | None = None
    ) -> None:
        """The runner stopped a `cancelling` job's subprocess (exit code: -signal on POSIX)."""
        with self._write() as s:
            _set(
                s,
                job_id,
                JobStatus.cancelling,
                attempt,
                status=JobStatus.cancelled.value,
                exit_code=exit_code,
                finished_at=_now(),
                log_tail=log_tail[-LOG_TAIL_CHARS:],
            )

    def release(self, job_id: str, attempt: int | None = None) -> None:
        """This process stops while the job runs: leave it for the next one (stale at once)."""
        with self._write() as s:
            _set(s, job_id, JobStatus.running, attempt, heartbeat_at=None)

    def recover(self, on_cancelled: Callable[[str], object] | None = None) -> list[str]:
        """Requeue `running` jobs of dead processes (or give up after `max_attempts`); finish
        their `cancelling` jobs as `cancelled`, then call `on_cancelled(run_dir)` for each (the
        runner stops a trainer still working there). Returns the requeued ids."""
        stale = _now() - timedelta(seconds=self.stale_after_s)
        owned = (JobStatus.running.value, JobStatus.cancelling.value)
        dead = select(TrainingJobRow).where(
            TrainingJobRow.status.in_(owned),
            or_(TrainingJobRow.heartbeat_at.is_(None), TrainingJobRow.heartbeat_at < stale),
        )
        with self._read() as s:
            if s.scalar(dead.limit(1)) is None:
                return []
        requeued, cancelled = [], []
        with self._write() as s:
            for row in s.scalars(dead):
                if row.status == JobStatus.cancelling.value:
                    row.status, row.finished_at = JobStatus.cancelled.value, _now()
                    row.log_tail = (row.log_tail + _RUNNER_DIED)[-LOG_TAIL_CHARS:]
                    cancelled.append(row.run_dir)
                elif row.attempts >= self.max_attempts:
                    row.status, row.finished_at = JobStatus.interrupted.value, _now()
                else:
                    row.status = JobStatus.queued.value
                    requeued.append(row.id)
        if on_cancelled is not None:
            for run_dir in cancelled:
                on_cancelled(run_dir)
        return requeued


def _set(
    session: Session, job_id: str, expected: JobStatus, attempt: int | None, **values: Any
) -> bool:
    """UPDATE the row only while it is still in status `expected` (and at `attempt`, unless
    None); True when it was."""
    query = update(TrainingJobRow).where(
        TrainingJobRow.id == job_id, TrainingJobRow.status == expected.value
    )
    if attempt is not None:
        query = query.where(TrainingJobRow.attempts == attempt)
    return bool(session.execute(query.values(**values)).rowcount)  # type: ignore[attr-defined]


def _job(row: TrainingJobRow) -> Job:
    return Job(
        id=row.id,
        spec=JobSpec.from_json(row.args),
        status=JobStatus(row.status),
        created_at=row.created_at,
        started_at=row.started_at,
        finished_at=row.finished_at,
        exit_code=row.exit_code,
        attempts=row.attempts,
        run_dir=row.run_dir,
        log_tail=row.log_tail,
    )


def _now() -> datetime:
    return datetime.now(UTC)


def _aware(t: datetime) -> datetime:
    return t if t.tzinfo else t.replace(tzinfo=UTC)  # SQLite returns naive UTC times


def _finished_status(exit_code: int) -> JobStatus:
    """The status of a job whose subprocess exited with `exit_code` by itself."""
    if exit_code == 0:
        return JobStatus.succeeded
    if exit_code == GATE_FAILED_EXIT_CODE:
        return JobStatus.gate_failed
    return JobStatus.failed
