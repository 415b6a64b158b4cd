"""`coexist serve` processes on loopback against a PostgreSQL schema of their own, for the
multi-replica and docker-topology tests (imported by them; not a test module).

| helper           | what                                                                  |
|------------------|-----------------------------------------------------------------------|
| `pg_schema_url`  | a store URL whose tables live in a fresh schema (dropped afterwards)  |
| `seed_zoo`       | a tiny registered zoo: task + impact nets of `ZOO_GOALS`, version 1   |
|                  | at `production`; `particle/task/a2` also has version 2 at `latest`    |
| `start_server`   | a `serve --no-bootstrap` subprocess; stdout and stderr (the logs) go  |
|                  | to files, never to a pipe nobody reads                                |
| `act_body`       | a valid `/v1/act` body for the seeded zoo                             |
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import psycopg
import pytest
import torch
from serve_process import COEXIST, free_port
from sqlalchemy.engine import make_url

from model_store.entities import Lineage
from model_store.naming import impact_model_name, task_model_name
from model_store.sql import SqlModelStore
from policy.qnet import QNetSpec, QNetwork, weights_to_safetensors

PG_URL = os.environ.get("COEXIST_TEST_PG_URL", "postgresql://postgres@127.0.0.1:5432/test")
ADMIN_TOKEN = "replica-test-token"
ZOO_GOALS = ("a2", "b3")
SPEC = QNetSpec(obs_dim=8, n_actions=5, hidden=(16,))
OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
REPO = Path(__file__).resolve().parents[2]


@contextmanager
def pg_schema_url() -> Iterator[str]:
    """A PostgreSQL URL selecting a fresh schema; skips (or fails under
    COEXIST_REQUIRE_POSTGRES) when no server answers."""
    schema = f"coexist_replicas_{uuid.uuid4().hex[:12]}"
    try:
        with psycopg.connect(PG_URL, autocommit=True, connect_timeout=3) as conn:
            conn.execute(f'CREATE SCHEMA "{schema}"')
    except psycopg.Error as exc:
        if os.environ.get("COEXIST_REQUIRE_POSTGRES"):
            pytest.fail(f"PostgreSQL not reachable at {PG_URL}: {exc}")
        pytest.skip(f"PostgreSQL not reachable at {PG_URL}: {exc}")
    url = make_url(PG_URL).update_query_dict({"options": f"-csearch_path={schema}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with psycopg.connect(PG_URL, autocommit=True) as conn:
            conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')


def _weights(seed: int) -> bytes:
    torch.manual_seed(seed)
    return weights_to_safetensors(QNetwork(SPEC))


def seed_zoo(store_url: str) -> None:
    """Register the tiny zoo of the module docstring."""
    with SqlModelStore(store_url) as store:
        for k, goal in enumerate(ZOO_GOALS):
            for kind, name in (("task", task_model_name), ("impact", impact_model_name)):
                store.create_model(
                    name("particle", goal),
                    env="particle",
                    kind=kind,
                    goals=(goal,),
                    obs_dim=8,
                    n_actions=5,
                )
                store.register_version(
                    name("particle", goal),
                    spec=SPEC.to_json(),
                    weights=_weights(10 * k + (kind == "impact")),
                    lineage=Lineage(config={"alpha": 0.05}, seed=k, registered_by="pytest"),
                    aliases=("latest", "production"),
                )
        store.register_version(
            task_model_name("particle", "a2"),
            spec=SPEC.to_json(),
            weights=_weights(99),
            lineage=Lineage(config={"alpha": 0.05}, seed=99, registered_by="pytest"),
        )


def act_body(**extra: Any) -> dict[str, Any]:
    body = {
        "env": "particle",
        "ego_goal": "a2",
        "observation": OBS,
        "partners": [{"index": 1, "goal": "b3"}],
        "seed": 1,
    }
    return {**body, **extra}


@dataclass
class Server:
    process: subprocess.Popen[bytes]
    http_url: str
    grpc_target: str
    log_path: Path  # stderr: the JSON logs

    def logs(self) -> list[str]:
        return self.log_path.read_text().splitlines()

    def stop(self, timeout: float = 30.0) -> int:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        return self.process.wait(timeout=timeout)


def server_env(store_url: str, data_dir: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("COEXIST_")}
    env.update(
        COEXIST_STORE_URL=store_url,
        COEXIST_ADMIN_TOKEN=ADMIN_TOKEN,
        COEXIST_DATA_DIR=str(data_dir),
        COEXIST_LOG_FORMAT="json",
        COEXIST_REFRESH_INTERVAL_S="0.3",
    )
    env.update(extra)
    return env


def start_server(
    name: str,
    env: dict[str, str],
    log_dir: Path,
    args: Sequence[str] = ("serve", "--no-bootstrap"),
    *,
    launcher: Sequence[str] = COEXIST,
    cwd: Path = REPO,
) -> Server:
    """`coexist <args> --host 127.0.0.1 --http-port P --grpc-port Q` (the last occurrence of an
    option wins, so `args` may carry other values for them); `launcher` runs `coexist`."""
    http_port, grpc_port = free_port(), free_port()
    cmd = [
        *launcher,
        *args,
        "--host",
        "127.0.0.1",
        "--http-port",
        str(http_port),
        "--grpc-port",
        str(grpc_port),
    ]
    log_path = log_dir / f"{name}.log"
    with open(log_dir / f"{name}.out", "wb") as out, open(log_path, "wb") as err:
        process = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=out, stderr=err)
    return Server(process, f"http://127.0.0.1:{http_port}", f"127.0.0.1:{grpc_port}", log_path)


# Generous: a server importing torch, or compiling its numba kernels afresh (an unpacked wheel
# has no kernel cache), on a 2-core machine busy with the rest of the suite.
READY_TIMEOUT_S = 240.0


def wait_ready(server: Server, timeout: float = READY_TIMEOUT_S) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if server.process.poll() is not None:
            raise AssertionError(f"server exited:\n{server.log_path.read_text()[-3000:]}")
        try:
            if httpx.get(f"{server.http_url}/readyz", timeout=1.0).status_code == 200:
                return
        except httpx.TransportError:
            pass
        time.sleep(0.1)
    raise AssertionError(f"server not ready:\n{server.log_path.read_text()[-3000:]}")


@contextmanager
def running(
    servers: Sequence[Server], timeout: float = READY_TIMEOUT_S
) -> Iterator[Sequence[Server]]:
    """Wait for every server to be ready (each within `timeout`); stop them all afterwards."""
    try:
        for server in servers:
            wait_ready(server, timeout)
        yield servers
    finally:
        for server in servers:
            try:
                server.stop()
            except subprocess.TimeoutExpired:
                server.process.kill()
