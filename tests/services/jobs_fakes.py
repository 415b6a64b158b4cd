"""Helpers of the job API tests (imported by them; not a test module): an app whose job runner
runs `jobs_fake_train.py` instead of `coexist train`, polling fast.

The fake's mode comes from the submitted job's seed (`MODES`), so one server runs every kind of
job: `{"kind": "task", "goals": "a2", "seed": SLEEP}` is a job that trains until cancelled.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from fastapi import FastAPI
from pydantic import SecretStr

from model_store.sql import SqlModelStore
from services.app import create_app
from services.settings import Settings
from trainer.jobs import JobRunner, JobSpec, JobTable

TOKEN = "jobs-cancel-t0ken"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
OK, FAIL, SLEEP, STUBBORN, REGISTER, SECRETS = range(6)
MODES = {
    OK: "ok",
    FAIL: "fail",
    SLEEP: "sleep",
    STUBBORN: "stubborn",
    REGISTER: "register",
    SECRETS: "secrets",
}
FAKE_TRAIN = Path(__file__).with_name("jobs_fake_train.py")
GRACE_S = 0.5  # SIGTERM -> SIGKILL in these tests


def fake_command(spec: JobSpec, run_dir: Path) -> list[str]:
    return [sys.executable, str(FAKE_TRAIN), MODES[spec.seed]]


def settings_for(tmp_path: Path) -> Settings:
    return Settings(
        admin_token=SecretStr(TOKEN),
        data_dir=tmp_path,
        store_url=f"sqlite:///{tmp_path / 'models.db'}",
        grpc_enabled=False,
    )


@contextmanager
def fake_jobs_app(tmp_path: Path) -> Iterator[FastAPI]:
    """The real app over a fresh SQLite store, its job runner running the fake trainer. No
    lifespan is needed: the runner starts on the first submit; it is stopped on the way out."""
    settings = settings_for(tmp_path)
    with SqlModelStore(settings.resolved_store_url()) as store:
        app = create_app(settings, store=store)
        table = JobTable(settings.resolved_store_url())
        runner = JobRunner(
            table,
            store_url=settings.resolved_store_url(),
            poll_s=0.05,
            heartbeat_s=0.5,
            cancel_grace_s=GRACE_S,
            command=fake_command,
        )
        app.state.jobs = table, runner
        try:
            yield app
        finally:
            runner.stop()
            table.close()


def wait_for(check: Callable[[], Any], what: str, timeout_s: float = 60.0) -> Any:
    """Poll `check` until it returns something truthy; fail naming `what` after `timeout_s`
    (generous: a trainer subprocess starts in seconds, but a loaded 2-core machine is slower)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if result := check():
            return result
        time.sleep(0.02)
    raise AssertionError(f"still waiting for {what} after {timeout_s} s")
