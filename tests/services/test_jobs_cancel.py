"""`DELETE /v1/jobs/{id}`: cancel queued and running jobs, refuse finished and unknown ones, need
the admin token, keep what was registered, and never resume a cancelled job after a restart.

The runner runs `jobs_fake_train.py` (see `jobs_fakes`), so nothing here trains for real."""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from jobs_fakes import (
    AUTH,
    FAIL,
    GRACE_S,
    OK,
    REGISTER,
    SLEEP,
    STUBBORN,
    fake_jobs_app,
    settings_for,
    wait_for,
)
from sqlalchemy import update

from model_store.sql import SqlModelStore
from model_store.sql.orm import TrainingJobRow
from trainer.jobs import JobSpec, JobStatus, JobTable


@pytest.fixture
def app(tmp_path: Path) -> Iterator[FastAPI]:
    with fake_jobs_app(tmp_path) as app:
        yield app


@pytest.fixture
def client(app: FastAPI) -> TestClient:
    return TestClient(app)  # no lifespan: the runner starts on the first submit


def _submit(client: TestClient, seed: int) -> str:
    answer = client.post(
        "/v1/jobs", json={"kind": "task", "goals": "a2", "seed": seed}, headers=AUTH
    )
    assert answer.status_code == 202, answer.json()
    job_id: str = answer.json()["id"]
    return job_id


def _job(client: TestClient, job_id: str) -> dict[str, Any]:
    job: dict[str, Any] = client.get(f"/v1/jobs/{job_id}").json()
    return job


def _log(client: TestClient, job_id: str) -> str:
    log: str = client.get(f"/v1/jobs/{job_id}/logs").json()["log"]
    return log


def _started_pid(client: TestClient, job_id: str) -> int:
    """Wait until the fake trainer says it has started; its process id."""
    found = wait_for(
        lambda: re.search(r"training started \(pid (\d+)\)", _log(client, job_id)),
        f"job {job_id} to start",
    )
    return int(found.group(1))


def _ended(client: TestClient, job_id: str) -> dict[str, Any]:
    def finished() -> dict[str, Any] | None:
        job = _job(client, job_id)
        return None if job["status"] in ("queued", "running", "cancelling") else job

    job: dict[str, Any] = wait_for(finished, f"job {job_id} to end")
    return job


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_a_cancelled_queued_job_never_starts(client: TestClient) -> None:
    running = _submit(client, SLEEP)
    _started_pid(client, running)
    queued = _submit(client, OK)  # one job at a time: this one waits behind the first
    answer = client.delete(f"/v1/jobs/{queued}", headers=AUTH)
    assert answer.status_code == 200, answer.json()
    assert answer.json()["status"] == "cancelled"
    assert "cancelled while queued" in _log(client, queued)
    assert client.delete(f"/v1/jobs/{running}", headers=AUTH).status_code == 202
    _ended(client, running)
    job = _job(client, queued)
    assert job["status"] == "cancelled" and job["attempts"] == 0 and job["started_at"] is None
    assert job["exit_code"] is None and job["finished_at"] is not None
    assert not Path(job["run_dir"]).exists()  # the runner never got to it


def test_cancelling_a_running_job_terminates_its_subprocess(client: TestClient) -> None:
    job_id = _submit(client, SLEEP)
    pid = _started_pid(client, job_id)
    answer = client.delete(f"/v1/jobs/{job_id}", headers=AUTH)
    assert answer.status_code == 202, answer.json()
    assert answer.json()["status"] in ("cancelling", "cancelled")
    job = _ended(client, job_id)
    assert job["status"] == "cancelled" and job["exit_code"] == -15  # SIGTERM
    assert job["finished_at"] is not None and job["attempts"] == 1
    assert _gone(pid)
    log = _log(client, job_id)
    assert "--- cancelled: stopping process group" in log
    assert "--- cancelled: ended on SIGTERM" in log and "exit code -15" in log


def test_a_subprocess_that_ignores_sigterm_is_killed_after_the_grace_period(
    client: TestClient,
) -> None:
    job_id = _submit(client, STUBBORN)
    pid = _started_pid(client, job_id)
    assert client.delete(f"/v1/jobs/{job_id}", headers=AUTH).status_code == 202
    job = _ended(client, job_id)
    assert job["status"] == "cancelled" and job["exit_code"] == -9  # SIGKILL
    stopped = datetime.fromisoformat(job["finished_at"]) - datetime.fromisoformat(job["started_at"])
    assert stopped.total_seconds() >= GRACE_S
    assert _gone(pid)
    assert f"killed (SIGKILL) after ignoring SIGTERM for {GRACE_S:g} s" in _log(client, job_id)


def test_networks_registered_before_the_cancel_stay(app: FastAPI, client: TestClient) -> None:
    job_id = _submit(client, REGISTER)
    _started_pid(client, job_id)  # it registers before it says so
    assert client.delete(f"/v1/jobs/{job_id}", headers=AUTH).status_code == 202
    assert _ended(client, job_id)["status"] == "cancelled"
    store = app.state.store
    version = store.get_version("particle/task/a2", 1)
    assert version.lineage.registered_by == "jobs_fake_train"
    assert store.load_weights("particle/task/a2", 1)  # whole: its sha256 is checked
    assert "registered particle/task/a2/1" in _log(client, job_id)


@pytest.mark.parametrize(("seed", "status"), [(OK, "succeeded"), (FAIL, "failed")])
def test_cancelling_a_finished_job_is_409_naming_its_status(
    client: TestClient, seed: int, status: str
) -> None:
    job_id = _submit(client, seed)
    assert _ended(client, job_id)["status"] == status
    answer = client.delete(f"/v1/jobs/{job_id}", headers=AUTH)
    assert answer.status_code == 409
    error = answer.json()
    assert error["code"] == "conflict" and error["field"] == "status"
    assert f"already {status}" in error["detail"]
    assert _job(client, job_id)["status"] == status  # untouched


def test_cancelling_twice_is_409_the_second_time(client: TestClient) -> None:
    job_id = _submit(client, SLEEP)
    _started_pid(client, job_id)
    assert client.delete(f"/v1/jobs/{job_id}", headers=AUTH).status_code == 202
    _ended(client, job_id)
    again = client.delete(f"/v1/jobs/{job_id}", headers=AUTH)
    assert again.status_code == 409 and "already cancelled" in again.json()["detail"]


def test_cancelling_an_unknown_job_is_404(client: TestClient) -> None:
    answer = client.delete("/v1/jobs/0123456789abcdef", headers=AUTH)
    assert answer.status_code == 404 and answer.json()["code"] == "not_found"


def test_cancelling_needs_the_admin_token(client: TestClient) -> None:
    job_id = _submit(client, SLEEP)
    _started_pid(client, job_id)
    assert client.delete(f"/v1/jobs/{job_id}").status_code == 401
    wrong = {"Authorization": "Bearer nope"}
    assert client.delete(f"/v1/jobs/{job_id}", headers=wrong).status_code == 403
    assert client.delete("/v1/jobs/unknown").status_code == 401  # auth before lookup
    assert _job(client, job_id)["status"] == "running"
    assert client.delete(f"/v1/jobs/{job_id}", headers=AUTH).status_code == 202
    _ended(client, job_id)


def test_a_job_left_cancelling_by_a_dead_server_is_not_resumed(tmp_path: Path) -> None:
    """The server died between the cancel and the end of the subprocess: the restarted server
    finishes the job as cancelled instead of putting it back in the queue."""
    settings = settings_for(tmp_path)
    with SqlModelStore(settings.resolved_store_url()):
        pass  # the schema
    table = JobTable(settings.resolved_store_url())
    job = table.submit(JobSpec("task", goals="a2", seed=OK), str(tmp_path / "jobs"))
    assert table.claim_next() is not None
    assert table.cancel(job.id).status is JobStatus.cancelling
    with table.engine.begin() as conn:  # what the dead server left: an old heartbeat
        old = datetime.now(UTC) - timedelta(minutes=5)
        conn.execute(update(TrainingJobRow).values(heartbeat_at=old))
    table.close()
    with fake_jobs_app(tmp_path) as app, TestClient(app) as client:  # lifespan: a restart
        job_json = _ended(client, job.id)
        assert job_json["status"] == "cancelled" and job_json["attempts"] == 1
        assert "runner died" in _log(client, job.id)  # attempts 1: never claimed again


def test_a_cancelled_job_stays_cancelled_across_a_restart(tmp_path: Path) -> None:
    with fake_jobs_app(tmp_path) as app:
        client = TestClient(app)
        job_id = _submit(client, SLEEP)
        _started_pid(client, job_id)
        client.delete(f"/v1/jobs/{job_id}", headers=AUTH)
        before = _ended(client, job_id)
    with fake_jobs_app(tmp_path) as app, TestClient(app) as client:
        assert not app.state.jobs[0].has_unfinished()
        assert app.state.jobs[0].claim_next() is None
        assert _job(client, job_id) == before


def test_a_cancel_that_comes_too_late_records_what_the_process_did(tmp_path: Path) -> None:
    with SqlModelStore(f"sqlite:///{tmp_path / 'm.db'}"):
        pass
    table = JobTable(f"sqlite:///{tmp_path / 'm.db'}")
    job = table.submit(JobSpec("task", goals="a2"), str(tmp_path))
    table.claim_next()
    table.cancel(job.id)
    table.finish(job.id, 0, "trained every batch")  # it exited before the runner stopped it
    done = table.get(job.id)
    assert done.status is JobStatus.succeeded and done.exit_code == 0
    table.close()
