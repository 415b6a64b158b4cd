"""`coexist jobs ...` against a real server (uvicorn, loopback) whose runner runs the fake trainer:
submit --wait (success and failure exit codes), list/status/logs output, cancel, and the one-line
errors for an unknown job, bad input, a missing token and an unreachable server."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from coexist_client.jobs import JobsClient
from http_live_server import live_http_server
from jobs_fakes import FAIL, OK, SLEEP, TOKEN, fake_jobs_app, wait_for
from typer.testing import CliRunner, Result

from cli.main import app as coexist


@pytest.fixture
def server(tmp_path: Path) -> Iterator[str]:
    with fake_jobs_app(tmp_path) as app, live_http_server(app) as url:
        yield url


def _jobs(server: str, *words: str, token: str | None = TOKEN) -> Result:
    args = ["jobs", *words, "--server", server]
    if token is not None:
        args += ["--token", token]
    env = {"COLUMNS": "200", "COEXIST_ADMIN_TOKEN": ""}  # tokens come from --token only
    return CliRunner().invoke(coexist, args, env=env)


def _job_id(output: str) -> str:
    found = re.search(r"job ([0-9a-f]{32}): ", output)
    assert found, output
    return found.group(1)


def test_submit_wait_exits_0_when_the_job_succeeds(server: str) -> None:
    result = _jobs(
        server,
        "submit",
        "task",
        "--goals",
        "a2",
        "--seed",
        str(OK),
        "--steps",
        "20",
        "--wait",
        "--poll",
        "0.05",
    )
    assert result.exit_code == 0, result.output
    job_id = _job_id(result.stdout)
    assert "queued (train task --env particle --goals a2 --seed 0 --steps 20)" in result.stdout
    assert f"job {job_id}: succeeded after" in result.stdout and "exit code 0" in result.stdout


def test_submit_wait_exits_1_and_shows_the_log_when_the_job_fails(server: str) -> None:
    result = _jobs(
        server, "submit", "impact", "--goals", "b3", "--seed", str(FAIL), "--wait", "--poll", "0.05"
    )
    assert result.exit_code == 1, result.output
    assert "failed after" in result.stdout and "exit code 3" in result.stdout
    assert "boom: the trainer failed" in result.stderr  # the log's last lines


def test_submit_without_wait_returns_at_once(server: str) -> None:
    result = _jobs(server, "submit", "task", "--goals", "a2", "--seed", str(SLEEP))
    assert result.exit_code == 0 and "queued" in result.stdout
    job_id = _job_id(result.stdout)
    with JobsClient(server, token=TOKEN) as client:
        assert client.get(job_id).status in ("queued", "running")
        client.cancel(job_id)


def test_list_status_and_logs_print_what_the_server_has(server: str) -> None:
    with JobsClient(server, token=TOKEN) as client:
        done = client.wait(client.submit("task", goals="a2", seed=OK, steps=20).id, poll_s=0.05)
        failed = client.wait(client.submit("zoo", combos="a2+b3", seed=FAIL).id, poll_s=0.05)
    listed = _jobs(server, "list")
    assert listed.exit_code == 0, listed.output
    rows = [line for line in listed.stdout.splitlines() if re.search(r"[0-9a-f]{32}", line)]
    assert [_row_id(r) for r in rows] == [failed.id, done.id]  # newest first
    assert "succeeded" in rows[1] and "env=particle goals=a2 seed=0 steps=20" in rows[1]
    assert "failed" in rows[0] and "combos=a2+b3" in rows[0] and "zoo" in rows[0]
    assert "2 job(s)" in listed.stdout
    shown = _jobs(server, "status", done.id)
    assert shown.exit_code == 0, shown.output
    fields = dict(
        re.split(r"\s{2,}", line.strip(), maxsplit=1) for line in shown.stdout.splitlines()
    )
    assert fields["status"] == "succeeded" and fields["exit code"] == "0"
    assert fields["train"] == "task --env particle --goals a2 --seed 0 --steps 20"
    assert fields["attempts"] == "1" and fields["run dir"] == done.run_dir
    logs = _jobs(server, "logs", done.id)
    assert logs.exit_code == 0 and "trained every batch" in logs.stdout
    assert logs.stdout.startswith("--- attempt 1:")
    assert _jobs(server, "logs", done.id, "--tail", "5").stdout == logs.stdout[-5:]


def _row_id(line: str) -> str:
    found = re.search(r"[0-9a-f]{32}", line)
    assert found
    return found.group(0)


def test_cancel_stops_a_running_job_and_logs_follow_to_the_end(server: str) -> None:
    with JobsClient(server, token=TOKEN) as client:
        job_id = client.submit("task", goals="a2", seed=SLEEP).id
        wait_for(lambda: "training started" in client.logs(job_id).text, "the job to start")
    cancelled = _jobs(server, "cancel", job_id, "--poll", "0.05")
    assert cancelled.exit_code == 0, cancelled.output
    assert f"job {job_id}: cancelling" in cancelled.stdout
    assert f"job {job_id}: cancelled after" in cancelled.stdout
    assert "exit code -15" in cancelled.stdout
    followed = _jobs(server, "logs", job_id, "--follow", "--poll", "0.05")
    assert followed.exit_code == 0
    assert (
        "training started" in followed.stdout
        and "--- cancelled: ended on SIGTERM" in followed.stdout
    )
    again = _jobs(server, "cancel", job_id)
    assert again.exit_code == 1 and "already cancelled" in again.stderr


def test_cancel_a_queued_job(server: str) -> None:
    with JobsClient(server, token=TOKEN) as client:
        first = client.submit("task", goals="a2", seed=SLEEP).id
        queued = client.submit("task", goals="b3", seed=OK).id
    result = _jobs(server, "cancel", queued)
    assert result.exit_code == 0 and f"job {queued}: cancelled while queued" in result.stdout
    assert _jobs(server, "cancel", first, "--poll", "0.05").exit_code == 0


def test_errors_are_one_line_with_an_exit_code(server: str) -> None:
    unknown = _jobs(server, "status", "0123456789abcdef")
    assert unknown.exit_code == 1 and unknown.stderr.startswith("error: job '0123456789abcdef'")
    bad = _jobs(server, "submit", "task", "--goals", "a2,zz9")
    assert bad.exit_code == 2 and "goals" in bad.stderr and "Traceback" not in bad.output
    kind = _jobs(server, "submit", "train")
    assert kind.exit_code == 2 and "kind: expected one of task, impact, joint, zoo" in kind.stderr
    anonymous = _jobs(server, "submit", "task", token=None)
    assert anonymous.exit_code == 1 and "--token or set COEXIST_ADMIN_TOKEN" in anonymous.stderr
    nowhere = _jobs("http://127.0.0.1:9", "list")
    assert nowhere.exit_code == 1 and nowhere.stderr.startswith("error: ")
    assert len(nowhere.stderr.strip().splitlines()) == 1


def test_the_token_can_come_from_the_environment(server: str) -> None:
    args = ["jobs", "submit", "task", "--goals", "a2", "--seed", str(OK), "--server", server]
    result = CliRunner().invoke(coexist, args, env={"COEXIST_ADMIN_TOKEN": TOKEN})
    assert result.exit_code == 0, result.output
