"""`coexist_client.JobsClient` against a real server (uvicorn, loopback) whose runner runs the
fake trainer: submit, wait, list, logs (whole, tail, followed), cancel, and the typed errors.
Also the byte-offset log reads the follower relies on (`trainer.jobs.runner.read_log_from`)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from coexist_client import CoexistError, InvalidArgument, NotFound, Unavailable
from coexist_client.errors import error_for_http
from coexist_client.jobs import JobInfo, JobsClient
from http_live_server import live_http_server
from jobs_fakes import FAIL, OK, SLEEP, TOKEN, fake_jobs_app

from trainer.jobs.runner import LOG_NAME, read_log_from


@pytest.fixture
def base_url(tmp_path: Path) -> Iterator[str]:
    with fake_jobs_app(tmp_path) as app, live_http_server(app) as url:
        yield url


@pytest.fixture
def jobs(base_url: str) -> Iterator[JobsClient]:
    with JobsClient(base_url, token=TOKEN) as client:
        yield client


def test_submit_wait_list_get_and_logs_round_trip(jobs: JobsClient) -> None:
    submitted = jobs.submit("task", goals="a2", seed=OK, steps=20)
    assert isinstance(submitted, JobInfo) and submitted.status == "queued"
    assert submitted.args["steps"] == 20 and submitted.created_at is not None
    seen: list[str] = []
    done = jobs.wait(submitted.id, poll_s=0.02, on_change=lambda j: seen.append(j.status))
    assert done.succeeded and done.finished and done.exit_code == 0 and done.attempts == 1
    assert seen[-1] == "succeeded" and len(seen) == len(set(seen))
    assert done.started_at is not None and done.finished_at is not None
    assert done.finished_at >= done.started_at
    assert jobs.get(done.id) == done
    failed = jobs.wait(jobs.submit("impact", goals="b3", seed=FAIL).id, poll_s=0.02)
    assert failed.status == "failed" and failed.exit_code == 3 and not failed.succeeded
    assert [j.id for j in jobs.list()] == [failed.id, done.id]  # newest first
    assert [j.id for j in jobs.list(limit=1)] == [failed.id]
    log = jobs.logs(done.id)
    assert log.status == "succeeded" and "trained every batch" in log.text
    assert log.text.startswith("--- attempt 1:") and log.next_offset is None
    assert jobs.logs(done.id, tail=10).text == log.text[-10:]


def test_cancel_and_follow_the_log_to_its_end(jobs: JobsClient) -> None:
    job = jobs.submit("task", goals="a2", seed=SLEEP)
    chunks: list[str] = []
    for chunk in jobs.follow_logs(job.id, poll_s=0.02):
        chunks.append(chunk)
        if "training started" in chunk:
            assert jobs.cancel(job.id).status in ("cancelling", "cancelled")
    text = "".join(chunks)
    assert text == jobs.logs(job.id).text  # every byte once, in order
    assert "--- cancelled: ended on SIGTERM" in text
    cancelled = jobs.get(job.id)
    assert cancelled.status == "cancelled" and cancelled.exit_code == -15


def test_errors_are_typed(jobs: JobsClient, base_url: str) -> None:
    with pytest.raises(NotFound):
        jobs.get("0123456789abcdef")
    with pytest.raises(InvalidArgument) as bad:
        jobs.submit("task", goals="a2,zz9")
    assert bad.value.field == "goals"
    done = jobs.wait(jobs.submit("task", goals="a2", seed=OK).id, poll_s=0.02)
    with pytest.raises(CoexistError) as conflict:
        jobs.cancel(done.id)
    assert conflict.value.code == error_for_http(409, "", None).code  # the SDK's 409 code
    assert "already succeeded" in conflict.value.message
    with JobsClient(base_url) as anonymous, pytest.raises(CoexistError) as no_token:
        anonymous.cancel(done.id)
    assert no_token.value.code == "unauthenticated"
    with JobsClient("http://127.0.0.1:9", timeout=2) as nowhere, pytest.raises(Unavailable):
        nowhere.list()


def test_wait_gives_up_after_its_timeout(jobs: JobsClient) -> None:
    job = jobs.submit("task", goals="a2", seed=SLEEP)
    with pytest.raises(TimeoutError, match="still"):
        jobs.wait(job.id, poll_s=0.02, timeout_s=0.2)
    jobs.cancel(job.id)
    assert jobs.wait(job.id, poll_s=0.02).status == "cancelled"


def test_log_reads_from_an_offset_never_split_a_character(tmp_path: Path) -> None:
    (tmp_path / LOG_NAME).write_bytes("héé €!".encode())  # 1 + 2 + 2 + 1 + 3 + 1 bytes
    assert read_log_from(tmp_path, 0, 2) == ("h", 1)  # 'é' would be cut in half: left out
    assert read_log_from(tmp_path, 1, 4) == ("éé", 5)
    assert read_log_from(tmp_path, 5, 3) == (" ", 6)
    assert read_log_from(tmp_path, 6, 100) == ("€!", 10)
    assert read_log_from(tmp_path, 10, 100) == ("", 10)
    assert read_log_from(tmp_path / "nowhere", 0, 100) is None
