"""A plugin as a user brings one, end to end: the tiny distribution of tests/envs/tinyline (an
environment and a store backend, registered only by entry points) is pip-installed into a
folder of its own, put on PYTHONPATH, and then, with nothing of coexist edited:

- its own tests pass (coexist's conformance check, coexist's store contract on its backend);
- `coexist env check tinyline`, `coexist train zoo --env tinyline`, `coexist serve`,
  `coexist run --env tinyline --server ...`, a training job through `POST /v1/jobs` and the
  console's live episode all work, every process finding the env by its entry point;
- the store URL's scheme `tinyline` picks the plugin's backend, which keeps no SQL database, in
  the CLI, the server, the job's subprocess and Ray workers (each writes its command into the
  backend's `opened` file); the job's networks land in that store, and the job table in the
  SQLite file the server keeps beside its data for a store without SQL."""

from __future__ import annotations

import json
import os
import secrets
import shutil
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import closing
from pathlib import Path

import httpx
import pytest
from serve_process import COEXIST, free_port, wait_ready

TINYLINE = Path(__file__).resolve().parents[1] / "envs" / "tinyline"
REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, str]]:
    """The plugin installed into its own folder; the environment every command runs with."""
    root = tmp_path_factory.mktemp("plugin")
    shutil.copytree(TINYLINE, root / "src", ignore=shutil.ignore_patterns("build", "*.egg-info"))
    pip = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation"]
    subprocess.run([*pip, "--target", str(root / "site"), str(root / "src")], check=True)
    (root / "data").mkdir()
    env = {
        **os.environ,
        "PYTHONPATH": str(root / "site"),
        "COEXIST_STORE_URL": f"tinyline://{root / 'data' / 'models'}",
        "COEXIST_DATA_DIR": str(root / "data"),
        "COEXIST_ADMIN_TOKEN": secrets.token_hex(16),
        "ROOT": str(root),
    }
    yield env


def _run(env: dict[str, str], *args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*COEXIST, *args], cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout
    )


def test_the_plugins_own_tests_pass(installed: dict[str, str]) -> None:
    src = Path(installed["ROOT"]) / "src"
    answer = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"],
        cwd=src,
        env=installed,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert answer.returncode == 0, answer.stdout[-3000:] + answer.stderr[-2000:]
    assert " passed" in answer.stdout


def test_check_train_serve_run_job_and_console(installed: dict[str, str]) -> None:
    env, root = installed, Path(installed["ROOT"])
    checked = _run(env, "env", "check", "tinyline", "--episodes", "1")
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert "tinyline: all 9 checks passed" in checked.stdout

    trained = _run(
        env, "train", "zoo", "--env", "tinyline", "--goals", "c1,c3", "--run-dir", str(root / "zoo")
    )
    assert trained.returncode == 0, trained.stdout[-3000:] + trained.stderr[-3000:]

    port = free_port()
    server = subprocess.Popen(
        [*COEXIST, "serve", "--no-bootstrap", "--http-port", str(port), "--grpc-port", "0"],
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        wait_ready(url, server)
        names = [e["name"] for e in httpx.get(f"{url}/v1/envs").json()["envs"]]
        assert "tinyline" in names and "particle" in names

        ran = _run(env, "run", "--env", "tinyline", "--ego", "c1", "--partners", "c3", "--server",
                   url, "--episodes", "2")  # fmt: skip
        assert ran.returncode == 0, ran.stdout + ran.stderr
        assert "agent_0 (ego)" in ran.stdout

        query = {"env": "tinyline", "ego_goal": "c1", "partners": "c3", "max_steps": "5"}
        stream = httpx.get(f"{url}/v1/console/episode", params=query).text
        lines = [json.loads(x) for x in stream.splitlines()]
        assert lines[0]["type"] == "episode" and lines[-1]["type"] == "end"
        assert lines[0]["scene"]["width"] == 5.0  # the plugin's drawing, numpy scalars and all
        assert lines[1]["lanes"][0]["agents"][0]["label"].startswith("agent 0 on c")

        headers = {"Authorization": f"Bearer {env['COEXIST_ADMIN_TOKEN']}"}
        body = {"kind": "task", "env": "tinyline", "goals": "c0", "steps": 100}
        job = httpx.post(f"{url}/v1/jobs", json=body, headers=headers)
        assert job.status_code in (200, 201, 202), job.text
        job_url = f"{url}/v1/jobs/{job.json()['id']}"
        deadline = time.monotonic() + 240
        while (status := httpx.get(job_url, headers=headers).json()["status"]) in (
            "queued",
            "running",
        ):
            assert time.monotonic() < deadline, "the job did not finish"
            time.sleep(1)
        assert status in ("succeeded", "gate_failed"), httpx.get(job_url, headers=headers).text
        served = httpx.get(f"{url}/v1/registry/models/tinyline/task/c0", headers=headers)
        assert served.status_code == 200, served.text
    finally:
        server.terminate()
        server.wait(timeout=30)

    opened = (root / "data" / "models" / "opened").read_text().splitlines()
    commands = {" ".join(line.split()[1:3]) for line in opened}
    # the CLI, the server and the job's subprocess each picked the backend by the scheme
    assert {"train zoo", "serve --no-bootstrap", "train task"} <= commands, opened
    # the job's network (c0: the zoo trained c1 and c3) is in the plugin's own files, and the
    # job's row in the SQLite file the server keeps beside its data for a store without SQL
    state = json.loads((root / "data" / "models" / "state.json").read_text())
    assert state["models"]["tinyline/task/c0"]["versions"], state["models"].keys()
    with closing(sqlite3.connect(root / "data" / "jobs.db")) as jobs:
        rows = jobs.execute("SELECT status FROM training_jobs").fetchall()
    assert rows == [(status,)]
    assert not (root / "data" / "models.db").exists()  # nothing fell back to coexist's SQL store


def test_ray_workers_open_the_store_by_its_scheme(installed: dict[str, str]) -> None:
    root = Path(installed["ROOT"])
    opened = root / "data" / "models" / "opened"
    before = opened.read_text().splitlines() if opened.exists() else []
    trained = _run(
        installed, "train", "task", "--env", "tinyline", "--goals", "c4", "--steps", "50",
        "--backend", "ray", "--run-dir", str(root / "ray"),
    )  # fmt: skip
    assert trained.returncode in (0, 4), trained.stdout[-3000:] + trained.stderr[-3000:]
    new = opened.read_text().splitlines()[len(before) :]
    # the CLI itself, and a Ray worker process (not a `coexist` command line)
    assert any(" train task" in line for line in new), new
    assert any(not line.split(" ", 1)[1].startswith(("train", "serve")) for line in new), new
