"""The training job API: submit, status, logs, auth, validation, and surviving a restart."""

from __future__ import annotations

import time
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from pydantic import SecretStr, ValidationError
from sqlalchemy import update

from model_store.errors import InvalidArgument
from model_store.sql import SqlModelStore
from model_store.sql.orm import TrainingJobRow
from services.app import create_app
from services.jobs_api import JobRequest
from services.settings import Settings
from trainer.jobs import JobSpec, JobStatus, JobTable, train_command
from trainer.jobs.spec import GATE_FAILED_EXIT_CODE, MAX_SEED, MAX_STEPS

TOKEN = "jobs-t0ken-for-the-tests"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
TINY = {"kind": "task", "goals": "a2", "steps": 20}


def _settings(tmp_path: Path) -> Settings:
    return Settings(
        admin_token=SecretStr(TOKEN),
        data_dir=tmp_path,
        store_url=f"sqlite:///{tmp_path / 'models.db'}",
        create_store=True,
        grpc_enabled=False,
    )


def _wait(client: TestClient, job_id: str, timeout_s: float = 90.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job: dict[str, Any] = client.get(f"/v1/jobs/{job_id}").json()
        if job["status"] not in ("queued", "running"):
            return job
        time.sleep(0.3)
    raise AssertionError(f"job {job_id} still {job['status']} after {timeout_s} s")


@pytest.fixture
def offline_client(tmp_path: Path) -> Iterator[TestClient]:
    """No lifespan: the runner starts only if a job is accepted (the tests here submit none),
    and is stopped with what it runs on the way out if one was."""
    settings = _settings(tmp_path)
    with SqlModelStore(settings.resolved_store_url()) as store:
        app = create_app(settings, store=store)
        yield TestClient(app)
        jobs = getattr(app.state, "jobs", None)
        if jobs is not None:
            jobs[1].stop()
            jobs[0].close()


@pytest.mark.slow
def test_submitted_job_trains_and_registers_the_network(tmp_path: Path) -> None:
    """20 steps train a network that fails its gate: the job trains and registers it, and ends
    `gate_failed` (not `succeeded`) with the gate's figures in its log."""
    settings = _settings(tmp_path)
    with TestClient(create_app(settings)) as client:
        answer = client.post("/v1/jobs", json=TINY, headers=AUTH)
        assert answer.status_code == 202
        assert answer.json()["status"] == "queued"
        job = _wait(client, answer.json()["id"])
        assert job["status"] == "gate_failed", client.get(f"/v1/jobs/{job['id']}/logs").json()
        assert job["exit_code"] == GATE_FAILED_EXIT_CODE and job["attempts"] == 1
        assert job["args"]["goals"] == "a2" and job["args"]["steps"] == 20
        assert Path(job["run_dir"]) == tmp_path / "jobs" / job["id"]
        log = client.get(f"/v1/jobs/{job['id']}/logs").json()["log"]
        assert "train task --env particle --goals a2" in log and "a2" in log.split("\n", 1)[1]
        assert "task a2..a2: 20/20 steps" in log  # progress lines: a log is not a terminal
        assert "gate failed: task a2: success_rate=" in log  # the gate's figures
        assert "own_target_return=" in log and "1 network(s) failed their gate" in log
        assert [j["id"] for j in client.get("/v1/jobs").json()["jobs"]] == [job["id"]]
    with SqlModelStore(settings.resolved_store_url()) as store:
        models = store.list_models().items
        assert models and all("a2" in m.goals for m in models)


def test_writes_need_the_admin_token(offline_client: TestClient) -> None:
    assert offline_client.post("/v1/jobs", json=TINY).status_code == 401
    wrong = {"Authorization": "Bearer nope"}
    assert offline_client.post("/v1/jobs", json=TINY, headers=wrong).status_code == 403
    assert offline_client.get("/v1/jobs").json() == {"jobs": []}


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"kind": "train"}, "kind"),
        ({"kind": "task", "goals": "a2,zz9"}, "goals"),
        ({"kind": "task", "env": "chess"}, "env"),
        ({"kind": "task", "steps": 0}, "steps"),
        ({"kind": "task", "combos": "a2+b3"}, "combos"),
        ({"kind": "joint"}, "combos"),
        ({"kind": "joint", "combos": "a2"}, "combos"),
        ({"kind": "zoo", "env": "cooking", "goals": "CarrotBanana", "combos": "a2+b3"}, "combos"),
        ({"kind": "task", "goals": "a2", "steps": 10**30}, "steps"),
        ({"kind": "task", "goals": "a2", "steps": 2**63 - 1}, "steps"),
        ({"kind": "task", "goals": "a2", "seed": 10**30}, "seed"),
        ({"kind": "task", "goals": "a2", "seed": -1}, "seed"),
        ({"kind": "task", "goals": "a2", "extra": 1}, "extra"),
        ({"kind": "task", "goals": "a2," * 100_000}, "goals"),
    ],
)
def test_bad_input_is_422_naming_the_field(
    offline_client: TestClient, body: dict[str, Any], field: str
) -> None:
    answer = offline_client.post("/v1/jobs", json=body, headers=AUTH)
    assert answer.status_code == 422, answer.json()
    assert answer.json()["field"] == field
    assert offline_client.get("/v1/jobs").json() == {"jobs": []}  # nothing was queued


def test_the_documented_ranges_hold_at_their_ends() -> None:
    """The largest seed and step count pass the route's model and the spec's checks; one more
    fails both (checked without submitting: a queued job would start training)."""
    ends = {"kind": "task", "goals": "a2", "seed": MAX_SEED, "steps": MAX_STEPS}
    JobSpec(**JobRequest.model_validate(ends).model_dump()).validate()
    for field in ("seed", "steps"):
        past = {**ends, field: ends[field] + 1}  # type: ignore[operator]
        with pytest.raises(ValidationError, match=field):
            JobRequest.model_validate(past)
        with pytest.raises(InvalidArgument, match=field):
            JobSpec(**past).validate()  # type: ignore[arg-type]


def test_unknown_job_is_404(offline_client: TestClient) -> None:
    answer = offline_client.get("/v1/jobs/nope")
    assert answer.status_code == 404 and answer.json()["code"] == "not_found"
    assert offline_client.get("/v1/jobs/nope/logs").status_code == 404


def test_train_command_always_resumes() -> None:
    spec = JobSpec("joint", combos="a2+b3", seed=3, steps=50).validate()
    cmd = train_command(spec, Path("/r/1"))  # no store URL: it travels in the environment
    assert cmd[1:] == [
        "-m",
        "cli.main",
        "train",
        "joint",
        "--env",
        "particle",
        "--combos",
        "a2+b3",
        "--seed",
        "3",
        "--steps",
        "50",
        "--run-dir",
        "/r/1",
        "--resume",
    ]
    with pytest.raises(InvalidArgument, match="goals"):
        JobSpec("impact", goals=" , ").validate()


def _die_while_running(table: JobTable, job_id: str) -> None:
    """What a killed server leaves: the row `running`, its heartbeat old."""
    claimed = table.claim_next()
    assert claimed is not None and claimed.id == job_id and claimed.status is JobStatus.running
    old = datetime.now(UTC) - timedelta(minutes=5)
    with table.engine.begin() as conn:
        conn.execute(update(TrainingJobRow).values(heartbeat_at=old))


def test_a_job_gives_up_after_max_attempts(tmp_path: Path) -> None:
    with SqlModelStore(f"sqlite:///{tmp_path / 'm.db'}"):
        pass
    table = JobTable(f"sqlite:///{tmp_path / 'm.db'}", max_attempts=2)
    job = table.submit(JobSpec("task", goals="a2"), str(tmp_path))
    fresh = table.submit(JobSpec("task", goals="b3"), str(tmp_path))
    _die_while_running(table, job.id)
    assert table.recover() == [job.id]  # the other job was never running: untouched
    assert table.get(fresh.id).status is JobStatus.queued
    _die_while_running(table, job.id)
    assert table.recover() == []
    gave_up = table.get(job.id)
    assert gave_up.status is JobStatus.interrupted and gave_up.attempts == 2
    table.close()


@pytest.mark.slow
def test_a_job_left_running_by_a_dead_server_is_resumed(tmp_path: Path) -> None:
    settings = _settings(tmp_path)
    with SqlModelStore(settings.resolved_store_url()):
        pass  # the schema
    table = JobTable(settings.resolved_store_url())
    job = table.submit(JobSpec("task", goals="a2", steps=20), str(tmp_path / "jobs"))
    _die_while_running(table, job.id)
    table.close()
    with TestClient(create_app(settings)) as client:  # the restarted server
        done = _wait(client, job.id)
    assert done["status"] == "gate_failed" and done["attempts"] == 2  # 20 steps: gate failed
    with SqlModelStore(settings.resolved_store_url()) as store:
        assert store.list_models().items
