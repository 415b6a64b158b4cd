"""The store's password stays secret through a training job: a real `coexist serve` over a
PostgreSQL role whose password is a unique marker runs a real `coexist train` job, and the
marker is in no job log, no process's command line (`ps -eww -o args`, sampled while the trainer
runs), no answer of any GET route, `/metrics`, nor the server's own logs. The trainer still
reaches the store (it registers its network): the URL travels in its environment.

The password travels apart from the URL: a job's subprocess, as the jobs API starts it, has it
in `PGPASSWORD` only, not in its command line nor in `COEXIST_STORE_URL` (read from `/proc`),
and its store and publish-lock connections send it. The test server trusts 127.0.0.1, so a
connection would succeed without any password: which password each connection sent is read from
the connection itself (libpq's `PQpass`), never inferred from its success.
"""

from __future__ import annotations

import re
import subprocess
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import psycopg
import pytest
from fastapi.testclient import TestClient
from jobs_fakes import AUTH as FAKE_AUTH
from jobs_fakes import SECRETS, TOKEN, fake_command, wait_for
from pydantic import SecretStr
from replica_cluster import (
    ADMIN_TOKEN,
    PG_URL,
    running,
    seed_zoo,
    server_env,
    start_server,
)
from sqlalchemy.engine import make_url

from model_store.errors import InvalidArgument
from model_store.sql import SqlModelStore
from model_store.sql.engine import normalise_url, redact_url
from services.app import create_app
from services.settings import Settings
from trainer.backends.once import lock_connection
from trainer.jobs.runner import read_log

AUTH = {"Authorization": f"Bearer {ADMIN_TOKEN}"}


@contextmanager
def role_with_password(marker: str) -> Iterator[str]:
    """A PostgreSQL role whose password is `marker`, owning a fresh schema: the URL of a store
    there (the password in it, as an operator would write it). Skips without a server."""
    name = f"coexist_secret_{uuid.uuid4().hex[:10]}"
    try:
        with psycopg.connect(PG_URL, autocommit=True, connect_timeout=3) as conn:
            conn.execute(f"CREATE ROLE \"{name}\" LOGIN PASSWORD '{marker}'")
            conn.execute(f'CREATE SCHEMA "{name}" AUTHORIZATION "{name}"')
    except psycopg.Error as exc:
        pytest.skip(f"PostgreSQL not reachable at {PG_URL}: {exc}")
    url = make_url(PG_URL).set(username=name, password=marker)
    url = url.update_query_dict({"options": f"-csearch_path={name}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with psycopg.connect(PG_URL, autocommit=True) as conn:
            conn.execute(f'DROP SCHEMA IF EXISTS "{name}" CASCADE')
            conn.execute(f'DROP ROLE IF EXISTS "{name}"')


class ProcessTable:
    """`ps -eww -o args` (whole command lines) sampled until stopped: every line ever seen."""

    def __init__(self) -> None:
        self.lines: set[str] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self) -> None:
        while not self._stop.is_set():
            out = subprocess.run(
                ["ps", "-eww", "-o", "args"], capture_output=True, text=True
            ).stdout
            self.lines.update(out.splitlines())
            time.sleep(0.02)

    def __enter__(self) -> ProcessTable:
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        self._thread.join()


def test_redact_url_hides_the_password_even_of_a_url_that_does_not_parse() -> None:
    assert redact_url("postgresql://u:s3cret@h:5432/db") == "postgresql://u:***@h:5432/db"
    assert "s3cret" not in redact_url(make_url("postgresql+psycopg://u:s3cret@h/db"))
    assert redact_url("sqlite:////abs/models.db") == "sqlite:////abs/models.db"
    assert "s3cret" not in redact_url("postgresql://u:s3cret@h:notaport/db")
    with pytest.raises(InvalidArgument) as refused:  # the parse error names the URL, masked
        normalise_url("postgresql://u:s3cret@h:notaport/db")
    assert "s3cret" not in str(refused.value) and "u:***@h" in str(refused.value)


@pytest.mark.postgres
@pytest.mark.slow
def test_a_jobs_store_password_is_in_no_log_command_line_or_answer(tmp_path: Path) -> None:
    marker = f"pw-marker-{uuid.uuid4().hex}"
    with role_with_password(marker) as store_url:
        assert marker in store_url
        seed_zoo(store_url)  # particle/task/a2 versions 1 and 2
        # The operator's own command line carries no URL either: the environment does.
        server = start_server("secret", server_env(store_url, tmp_path / "data"), tmp_path)
        with running([server]):
            base = server.http_url
            with ProcessTable() as ps:
                job = httpx.post(
                    f"{base}/v1/jobs",
                    json={"kind": "task", "goals": "a2", "steps": 20},
                    headers=AUTH,
                ).json()
                deadline = time.monotonic() + 180
                while time.monotonic() < deadline:
                    job = httpx.get(f"{base}/v1/jobs/{job['id']}").json()
                    if job["status"] not in ("queued", "running"):
                        break
                    time.sleep(0.2)
            logs = httpx.get(f"{base}/v1/jobs/{job['id']}/logs").json()["log"]
            # 20 steps train a network that fails its gate: the job ran the trainer to the end
            assert job["status"] in ("succeeded", "gate_failed"), logs
            trainer_lines = [line for line in ps.lines if job["id"] in line and "train" in line]
            assert trainer_lines, "the sampler never saw the trainer's command line"
            assert not [line for line in ps.lines if marker in line]
            assert "train task --env particle --goals a2" in logs and marker not in logs
            # the trainer reached the store through its environment: its network is there
            versions = httpx.get(
                f"{base}/v1/registry/models/particle/task/a2/-/versions", headers=AUTH
            ).json()
            assert [v["version"] for v in versions] == [3, 2, 1], versions

            answers: list[tuple[str, int, str]] = []
            paths = httpx.get(f"{base}/openapi.json").json()["paths"]
            gets = [p for p, ops in paths.items() if "get" in ops and "{" not in p]
            gets += [f"/v1/jobs/{job['id']}", f"/v1/jobs/{job['id']}/logs?offset=0"]
            assert "/metrics" in gets and "/readyz" in gets
            for path in gets:
                answer = httpx.get(f"{base}{path}", headers=AUTH, timeout=30)
                answers.append((path, answer.status_code, answer.text))
            assert not [(p, code) for p, code, _ in answers if code >= 500]
            leaked = [(p, text[:200]) for p, _, text in answers if marker in text]
            assert not leaked, leaked
        for log_file in tmp_path.glob("secret.*"):  # the server's stdout and stderr
            assert marker not in log_file.read_text(errors="replace"), log_file.name
        for file in (tmp_path / "data").rglob("*"):  # the job's run directory, log included
            if file.is_file():
                assert marker.encode() not in file.read_bytes(), file


def _proc_environ(pid: int) -> dict[str, str]:
    raw = Path(f"/proc/{pid}/environ").read_bytes().decode(errors="replace")
    return dict(item.split("=", 1) for item in raw.split("\0") if "=" in item)


@pytest.mark.postgres
@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="reads /proc")
def test_a_job_subprocess_gets_the_password_apart_from_the_url(tmp_path: Path) -> None:
    marker = f"pw-marker-{uuid.uuid4().hex}"
    with role_with_password(marker) as store_url, SqlModelStore(store_url) as store:
        role = make_url(store_url).username
        settings = Settings(
            admin_token=SecretStr(TOKEN), data_dir=tmp_path, store_url=store_url, grpc_enabled=False
        )
        app = create_app(settings, store=store)
        client = TestClient(app)  # no lifespan: the job table and runner open on first use
        assert client.get("/v1/jobs", headers=FAKE_AUTH).status_code == 200
        table, runner = app.state.jobs  # as the jobs API built them from the store
        runner.command = fake_command  # only the trainer is stood in for, argv and env are real
        try:
            # the server's own connections get the password from the URL object, not `***`
            with lock_connection(store.url) as conn:
                assert conn.info.password == marker
            raw = table.engine.raw_connection()
            assert raw.driver_connection is not None  # psycopg's own connection
            assert raw.driver_connection.info.password == marker
            raw.close()

            answer = client.post(
                "/v1/jobs", json={"kind": "task", "goals": "a2", "seed": SECRETS}, headers=FAKE_AUTH
            )
            assert answer.status_code == 202, answer.json()
            run_dir = answer.json()["run_dir"]
            started = wait_for(
                lambda: re.search(r"training started \(pid (\d+)\)", read_log(run_dir, 8000)),
                "the fake trainer to start",
            )
            pid = int(started.group(1))
            argv = Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")
            environ = _proc_environ(pid)
            assert "jobs_fake_train.py" in argv and marker not in argv
            assert make_url(environ["COEXIST_STORE_URL"]).username == role
            assert marker not in environ["COEXIST_STORE_URL"]
            assert environ["PGPASSWORD"] == marker  # apart, and only there
            assert [name for name, value in environ.items() if marker in value] == ["PGPASSWORD"]

            log = read_log(run_dir, 8000)
            assert "registered particle/task/a2/1" in log, log  # it reached the store
            assert "store connection password: PGPASSWORD" in log, log
            assert "publish lock connection password: PGPASSWORD" in log, log
            assert marker not in log
            assert store.get_version("particle/task/a2", 1).lineage.registered_by
        finally:
            runner.stop()
            table.close()
