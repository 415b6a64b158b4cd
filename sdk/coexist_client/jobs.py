"""`JobsClient` (sync) and `AsyncJobsClient`: the server's training job API over HTTP, typed.

    with JobsClient("http://127.0.0.1:8000", token="...") as jobs:
        job = jobs.submit("task", goals="a2", steps=2_000)
        done = jobs.wait(job.id)                   # polls until the job has ended
        print(done.status, done.exit_code, jobs.logs(done.id).text)

| method                        | route                          | returns         |
|-------------------------------|--------------------------------|-----------------|
| `submit(kind, ...)`           | `POST /v1/jobs`                | `JobInfo`       |
| `list(limit=100)`             | `GET /v1/jobs`                 | `list[JobInfo]` |
| `get(id)`                     | `GET /v1/jobs/{id}`            | `JobInfo`       |
| `logs(id, tail=, offset=)`    | `GET /v1/jobs/{id}/logs`       | `JobLog`        |
| `cancel(id)`                  | `DELETE /v1/jobs/{id}`         | `JobInfo`       |
| `wait(id, ...)` (sync)        | `GET /v1/jobs/{id}`, polled    | `JobInfo`       |
| `follow_logs(id, ...)` (sync) | `GET /v1/jobs/{id}/logs?offset`| chunks of text  |

`token` is sent as `Authorization: Bearer <token>`: the admin token for submit and cancel, the read
token (or the admin one) for the rest when the server wants one. Errors are the SDK's
(`coexist_client.errors`): `InvalidArgument` (422, names the field), `NotFound` (404), `Unavailable`;
cancelling a finished job is the SDK's error for HTTP 409 (a `CoexistError` whose message names the
job's status), a missing or wrong token one with code `unauthenticated` / `permission_denied`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from coexist_client.exchange import AsyncClosing, Closing, Core, Plan, awaiting, blocking
from coexist_client.transport import Http, HttpTransport

DEFAULT_URL = "http://127.0.0.1:8000"

# A job in one of these has ended: no runner touches it again.
FINISHED_STATUSES = frozenset({"succeeded", "failed", "gate_failed", "interrupted", "cancelled"})


def _time(value: str | None) -> datetime | None:
    return None if value is None else datetime.fromisoformat(value)


@dataclass(frozen=True)
class JobInfo:
    """A training job as the server reports it (`args`: kind, env, goals, combos, seed, steps)."""

    id: str
    kind: str
    status: str
    args: Mapping[str, Any] = field(default_factory=dict)
    created_at: datetime | None = None
    started_at: datetime | None = None
    finished_at: datetime | None = None
    exit_code: int | None = None
    attempts: int = 0
    run_dir: str = ""

    @property
    def finished(self) -> bool:
        return self.status in FINISHED_STATUSES

    @property
    def succeeded(self) -> bool:
        return self.status == "succeeded"

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> JobInfo:
        return cls(
            id=str(data["id"]),
            kind=str(data["kind"]),
            status=str(data["status"]),
            args=dict(data.get("args") or {}),
            created_at=_time(data.get("created_at")),
            started_at=_time(data.get("started_at")),
            finished_at=_time(data.get("finished_at")),
            exit_code=data.get("exit_code"),
            attempts=int(data.get("attempts", 0)),
            run_dir=str(data.get("run_dir", "")),
        )


@dataclass(frozen=True)
class JobLog:
    """A piece of a job's log; `next_offset` (asked with an offset) is where the next one starts."""

    id: str
    status: str
    text: str
    next_offset: int | None = None


class JobsCore(Core):
    def __init__(self, base_url: str = DEFAULT_URL, *, aio: bool = False, **options: Any) -> None:
        """`options`: `HttpTransport`'s (token, timeout, headers, verify, transport, retry)."""
        self.transport = HttpTransport(base_url, aio=aio, **options)


def submit(
    core: JobsCore,
    kind: str,
    *,
    env: str = "particle",
    goals: str = "all",
    combos: str = "",
    seed: int = 0,
    steps: int | None = None,
) -> Plan[JobInfo]:
    """Queue `coexist train <kind> ...` on the server (the server's `trainer.jobs.spec` rules)."""
    body: dict[str, Any] = {
        "kind": kind,
        "env": env,
        "goals": goals,
        "combos": combos,
        "seed": seed,
    }
    if steps is not None:
        body["steps"] = steps
    return JobInfo.from_json((yield Http("POST", "/v1/jobs", body, idempotent=False)))


def list_jobs(core: JobsCore, limit: int = 100) -> Plan[list[JobInfo]]:
    """The newest `limit` jobs, newest first."""
    data = yield Http("GET", "/v1/jobs", params={"limit": limit})
    return [JobInfo.from_json(j) for j in data["jobs"]]


def get(core: JobsCore, job_id: str) -> Plan[JobInfo]:
    """One job's status."""
    return JobInfo.from_json((yield Http("GET", f"/v1/jobs/{job_id}")))


def logs(
    core: JobsCore, job_id: str, *, tail: int | None = None, offset: int | None = None
) -> Plan[JobLog]:
    """The last `tail` characters (server default 64 000), or the log from byte `offset` on."""
    params = {k: v for k, v in (("tail", tail), ("offset", offset)) if v is not None}
    data = yield Http("GET", f"/v1/jobs/{job_id}/logs", params=params)
    return JobLog(data["id"], data["status"], data["log"], data.get("next_offset"))


def cancel(core: JobsCore, job_id: str) -> Plan[JobInfo]:
    """Cancel: a queued job comes back `cancelled`, a running one `cancelling` (see `wait`)."""
    return JobInfo.from_json((yield Http("DELETE", f"/v1/jobs/{job_id}")))


class JobsClient(JobsCore, Closing):
    """Synchronous client of the job API; see the module docstring."""

    submit = blocking(submit)
    list = blocking(list_jobs)
    get = blocking(get)
    logs = blocking(logs)
    cancel = blocking(cancel)

    def wait(
        self,
        job_id: str,
        *,
        poll_s: float = 1.0,
        timeout_s: float | None = None,
        on_change: Callable[[JobInfo], None] | None = None,
    ) -> JobInfo:
        """Poll until the job has ended; `on_change` sees every new status (the first one too).
        Raises `TimeoutError` after `timeout_s` (None: wait as long as it takes)."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        last_status = None
        while True:
            job = self.get(job_id)
            if on_change is not None and job.status != last_status:
                on_change(job)
            last_status = job.status
            if job.finished:
                return job
            if deadline is not None and time.monotonic() >= deadline:
                raise TimeoutError(f"job {job_id} is still {job.status} after {timeout_s} s")
            time.sleep(poll_s)

    def follow_logs(self, job_id: str, *, poll_s: float = 1.0, offset: int = 0) -> Iterator[str]:
        """Yield the log as it grows, from byte `offset` on, until the job has ended and all of
        its log has been read."""
        while True:
            piece = self.logs(job_id, offset=offset)
            if piece.text:
                yield piece.text
            moved = piece.next_offset is not None and piece.next_offset != offset
            offset = piece.next_offset if piece.next_offset is not None else offset
            if piece.status in FINISHED_STATUSES and not moved:
                return
            if not moved:
                time.sleep(poll_s)


class AsyncJobsClient(JobsCore, AsyncClosing):
    """The job API, awaited (`aclose()` to close)."""

    def __init__(self, base_url: str = DEFAULT_URL, **options: Any) -> None:
        super().__init__(base_url, aio=True, **options)

    submit = awaiting(submit)
    list = awaiting(list_jobs)
    get = awaiting(get)
    logs = awaiting(logs)
    cancel = awaiting(cancel)
