"""One trainer per job against a real `coexist serve` and the real `coexist train`: `kill -9` of
the server while its job trains takes the trainer with it; the restarted server resumes the job
with exactly one trainer (attempt 2, the same run directory); cancelling it stops that one and
leaves none. The job trains for real (one torch thread) until it is cancelled."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest
from live_serve import AUTH, serving

LEASE_S = "3"  # COEXIST_JOB_LEASE_S: the restarted server resumes the job this soon
JOB = {"kind": "task", "goals": "a2", "seed": 3, "steps": 1_000_000}


def trainers(run_dir: str) -> list[int]:
    """Live processes whose command line names the run directory (the job's trainers)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes()
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if run_dir.encode() in cmdline and state != "Z":
            found.append(int(entry.name))
    return found


def wait_for(check: Callable[[], Any], what: str, timeout_s: float = 60.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if result := check():
            return result
        time.sleep(0.1)
    raise AssertionError(f"still waiting for {what} after {timeout_s} s")


def _job(url: str, job_id: str) -> dict[str, Any]:
    job: dict[str, Any] = httpx.get(f"{url}/v1/jobs/{job_id}", headers=AUTH).json()
    return job


@pytest.mark.slow
def test_a_job_runs_once_whatever_dies(tmp_path: Path) -> None:
    store_url = f"sqlite:///{tmp_path / 'models.db'}"
    env = {"COEXIST_JOB_LEASE_S": LEASE_S, "COEXIST_CREATE_STORE": "1"}  # a new, empty store
    orphans: list[int] = []
    try:
        with serving(tmp_path, store_url, name="first", ready=False, **env) as first:
            answer = httpx.post(f"{first.http_url}/v1/jobs", json=JOB, headers=AUTH)
            assert answer.status_code == 202, answer.text
            job_id, run_dir = answer.json()["id"], answer.json()["run_dir"]
            (pid,) = wait_for(lambda: trainers(run_dir), "the first trainer")
            assert _job(first.http_url, job_id)["status"] == "running"
            first.process.send_signal(signal.SIGKILL)
            first.process.wait()
            try:
                wait_for(lambda: not trainers(run_dir), "the trainer to die with its server", 10)
            except AssertionError:
                orphans = trainers(run_dir)
                raise
        with serving(tmp_path, store_url, name="second", ready=False, **env) as second:
            resumed = wait_for(lambda: trainers(run_dir), "the resumed trainer")
            assert len(resumed) == 1 and resumed[0] != pid
            job = wait_for(
                lambda: (j := _job(second.http_url, job_id))["attempts"] == 2 and j, "attempt 2"
            )
            assert job["status"] == "running" and job["run_dir"] == run_dir
            time.sleep(float(LEASE_S))  # a lease later there is still one trainer
            assert trainers(run_dir) == resumed
            cancel = httpx.delete(f"{second.http_url}/v1/jobs/{job_id}", headers=AUTH)
            assert cancel.status_code == 202, cancel.text
            wait_for(lambda: _job(second.http_url, job_id)["status"] == "cancelled", "the cancel")
            assert trainers(run_dir) == []
            log = httpx.get(f"{second.http_url}/v1/jobs/{job_id}/logs", headers=AUTH).json()
            assert log["log"].count("--- attempt") == 2
    finally:
        for orphan in orphans:  # what today's code leaves behind: do not let it train on
            os.killpg(orphan, signal.SIGKILL)
