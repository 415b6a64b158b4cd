"""`trainer.jobs.leash` and the runner's use of it, with real processes: a leashed trainer dies
with the process that started it, holds its run directory while it lives, and is stopped before
the next attempt starts there; a runner that loses its job's lease stops its trainer; a job
recovered as cancelled has a trainer still working in its directory stopped. (The whole story
against `coexist serve` and `coexist train`: tests/services/test_jobs_one_trainer.py.)"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import update

from model_store.sql import SqlModelStore
from model_store.sql.orm import TrainingJobRow
from trainer.jobs import JobRunner, JobSpec, JobStatus, JobTable
from trainer.jobs.leash import LOCKED, leashed, lock_holder

SLEEPER = "import os, time; print('training started', os.getpid(), flush=True); time.sleep(60)"
STUBBORN = "import signal; signal.signal(signal.SIGTERM, signal.SIG_IGN); " + SLEEPER


def wait_for(check: Callable[[], Any], what: str, timeout_s: float = 15.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if result := check():
            return result
        time.sleep(0.05)
    raise AssertionError(f"still waiting for {what} after {timeout_s} s")


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    return state != "Z"


def sleeper(spec: JobSpec, run_dir: Path) -> list[str]:
    return [sys.executable, "-c", SLEEPER]


@pytest.fixture
def table(tmp_path: Path) -> Iterator[JobTable]:
    url = f"sqlite:///{tmp_path / 'models.db'}"
    with SqlModelStore(url):
        pass  # the schema
    jobs = JobTable(url, stale_after_s=2.0)
    yield jobs
    jobs.close()


@pytest.fixture
def leftovers() -> Iterator[list[subprocess.Popen[bytes]]]:
    """Processes a test starts itself; killed on the way out, whatever happened."""
    started: list[subprocess.Popen[bytes]] = []
    yield started
    for proc in started:
        if proc.poll() is None:
            proc.kill()
        proc.wait()


def _left_running_by_a_dead_runner(table: JobTable, run_root: Path, cancel: bool = False) -> str:
    """A job claimed once (attempt 1) whose runner died: its heartbeat is long past."""
    job = table.submit(JobSpec("task", goals="a2"), str(run_root))
    assert table.claim_next() is not None
    if cancel:
        table.cancel(job.id)
    with table.engine.begin() as conn:
        old = datetime.now(UTC) - timedelta(minutes=5)
        conn.execute(update(TrainingJobRow).values(heartbeat_at=old))
    return job.id


def _log(run_dir: str) -> str:
    path = Path(run_dir) / "log.txt"
    return path.read_text() if path.exists() else ""


def _started(run_dir: str) -> list[int]:
    """The pids the trainers of the job's log said they started with, in order."""
    return [int(pid) for pid in re.findall(r"^training started (\d+)$", _log(run_dir), re.M)]


def test_a_leashed_process_dies_with_its_parent(tmp_path: Path) -> None:
    """The parent is killed with SIGKILL: its leashed child goes too, and lets the lock go."""
    run_dir = tmp_path / "run"
    parent_code = (
        "import subprocess, sys, time; from trainer.jobs.leash import leashed; "
        f"child = subprocess.Popen(leashed([sys.executable, '-c', {SLEEPER!r}], {str(run_dir)!r}), "
        "stdout=sys.stdout); time.sleep(60)"
    )
    parent = subprocess.Popen([sys.executable, "-c", parent_code], stdout=subprocess.PIPE)
    try:
        assert parent.stdout is not None
        pid = int(parent.stdout.readline().split()[-1])
        assert lock_holder(run_dir) == pid
        parent.kill()
        parent.wait()
        wait_for(lambda: not alive(pid), "the child to die with its parent", 5.0)
        assert lock_holder(run_dir) is None
    finally:
        if parent.poll() is None:
            parent.kill()


def test_the_leash_refuses_a_directory_another_trainer_holds(
    tmp_path: Path, leftovers: list[subprocess.Popen[bytes]]
) -> None:
    first = subprocess.Popen(
        leashed([sys.executable, "-c", SLEEPER], tmp_path), stdout=subprocess.PIPE
    )
    leftovers.append(first)
    assert first.stdout is not None and first.stdout.readline()
    second = subprocess.run(leashed([sys.executable, "-c", SLEEPER], tmp_path), timeout=30)
    assert second.returncode == LOCKED
    assert lock_holder(tmp_path) == first.pid


def test_the_next_attempt_stops_a_leftover_trainer(
    table: JobTable, tmp_path: Path, leftovers: list[subprocess.Popen[bytes]]
) -> None:
    """A trainer of attempt 1 outlived its runner (and ignores SIGTERM): attempt 2 kills it
    before it starts, so only one trainer ever works in the directory."""
    job_id = _left_running_by_a_dead_runner(table, tmp_path / "jobs")
    run_dir = table.get(job_id).run_dir
    old = subprocess.Popen(
        leashed([sys.executable, "-c", STUBBORN], run_dir), stdout=subprocess.PIPE
    )
    leftovers.append(old)
    assert old.stdout is not None and old.stdout.readline()
    runner = JobRunner(table, store_url="unused", poll_s=0.05, cancel_grace_s=0.5, command=sleeper)
    runner.start()
    try:
        wait_for(lambda: _started(run_dir), "attempt 2 to start")
        assert old.wait(timeout=5) == -9  # SIGKILL: it ignored the SIGTERM
        log = _log(run_dir)
        assert f"(pid {old.pid}) still held the run directory: stopped it (SIGKILL)" in log
        (new_pid,) = _started(run_dir)
        assert lock_holder(run_dir) == new_pid != old.pid
        job = table.get(job_id)
        assert job.status is JobStatus.running and job.attempts == 2
        table.cancel(job_id)
        runner.wake()
        wait_for(lambda: table.get(job_id).status is JobStatus.cancelled, "the cancel")
        assert not alive(new_pid) and lock_holder(run_dir) is None
    finally:
        runner.stop()


def test_a_runner_that_loses_its_lease_stops_its_trainer(table: JobTable, tmp_path: Path) -> None:
    """Another server recovered the job and claimed it again (attempt 2) while this runner
    could not renew: at its next renewal the runner stops its trainer and records nothing."""
    job = table.submit(JobSpec("task", goals="a2"), str(tmp_path / "jobs"))
    runner = JobRunner(
        table,
        store_url="unused",
        poll_s=0.05,
        heartbeat_s=0.1,
        cancel_grace_s=0.5,
        command=sleeper,
    )
    runner.start()
    try:
        (pid,) = wait_for(lambda: _started(job.run_dir), "the trainer")
        assert lock_holder(job.run_dir) == pid
        with table.engine.begin() as conn:  # the takeover, as another server's claim does it
            conn.execute(update(TrainingJobRow).values(attempts=TrainingJobRow.attempts + 1))
        wait_for(lambda: not alive(pid), "the trainer to be stopped")
        assert "--- lease lost (it was taken over)" in _log(job.run_dir)
        after = table.get(job.id)
        assert after.status is JobStatus.running and after.attempts == 2 and after.exit_code is None
    finally:
        runner.stop()


def test_a_job_recovered_as_cancelled_has_its_leftover_trainer_stopped(
    table: JobTable, tmp_path: Path, leftovers: list[subprocess.Popen[bytes]]
) -> None:
    job_id = _left_running_by_a_dead_runner(table, tmp_path / "jobs", cancel=True)
    run_dir = table.get(job_id).run_dir
    old = subprocess.Popen(
        leashed([sys.executable, "-c", SLEEPER], run_dir), stdout=subprocess.PIPE
    )
    leftovers.append(old)
    assert old.stdout is not None and old.stdout.readline()
    Path(run_dir, "log.txt").write_text("--- attempt 1\n")
    runner = JobRunner(table, store_url="unused", poll_s=0.05, cancel_grace_s=0.5, command=sleeper)
    runner.start()
    try:
        assert old.wait(timeout=10) == -15  # SIGTERM
        assert table.get(job_id).status is JobStatus.cancelled
        stopped = "still held the run directory: stopped it (SIGTERM)"
        wait_for(lambda: stopped in _log(run_dir), "the log to say so")
    finally:
        runner.stop()
