"""`coexist serve` as a user runs it: a real process, REST and gRPC, graceful stop; bootstrap."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from coexist_client import CoexistClient, GrpcCoexistClient
from serve_process import OBS, free_port, serve_command, wait_ready

from model_store.sql import SqlModelStore


@pytest.mark.parametrize("workers", [1, 2])
def test_serve_answers_rest_and_grpc_then_stops_gracefully(
    tiny_zoo_store: SqlModelStore, tmp_path: Path, workers: int
) -> None:
    """With two uvicorn workers both bind the gRPC port too (SO_REUSEPORT)."""
    http_port, grpc_port = free_port(), free_port()
    env = {**os.environ, "COEXIST_DEV_MODE": "1", "COEXIST_DATA_DIR": str(tmp_path)}
    store_url = tiny_zoo_store.url.render_as_string(hide_password=False)
    cmd = serve_command(store_url, http_port, grpc_port, "--workers", str(workers))
    process = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        url = f"http://127.0.0.1:{http_port}"
        wait_ready(url, process)
        partners = {1: "b3"}
        with CoexistClient(url) as rest, GrpcCoexistClient(f"127.0.0.1:{grpc_port}") as grpc:
            a = rest.act("particle", "a2", OBS, partners=partners, seed=3)
            answers = [grpc.act("particle", "a2", OBS, partners=partners, seed=3) for _ in range(4)]
            b = answers[0]
        assert all(x.probs == b.probs for x in answers)
        assert a.probs == pytest.approx(b.probs, abs=1e-12)
        assert a.action == b.action and a.models == b.models
    finally:
        process.send_signal(signal.SIGTERM)
        out, _ = process.communicate(timeout=30)
    # uvicorn finishes in-flight work and the lifespan (gRPC stop, engine, store), then
    # re-raises SIGTERM so the exit status says how the process ended
    assert process.returncode in (0, -signal.SIGTERM), out.decode()
    assert b"Application shutdown complete" in out


def test_serve_refuses_the_default_token_outside_dev_mode(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("COEXIST_")}
    env["COEXIST_DATA_DIR"] = str(tmp_path)
    result = subprocess.run(
        [sys.executable, "-m", "cli.main", "serve", "--no-bootstrap"],
        env=env,
        capture_output=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert b"COEXIST_ADMIN_TOKEN" in result.stderr


def test_serve_names_an_unusable_session_store(tmp_path: Path) -> None:
    """A session store URL of another scheme stops `serve` before it starts, password unshown
    (a missing COEXIST_SESSION_SECRET is `Settings.check_secure`'s, tested with the routes)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("COEXIST_")}
    env.update(
        COEXIST_DATA_DIR=str(tmp_path),
        COEXIST_DEV_MODE="1",
        COEXIST_SESSION_STORE_URL="mysql://u:hunter2-not-shown@db/x",
        COEXIST_SESSION_SECRET="a-long-random-session-secret-1f3b",
    )
    result = subprocess.run(
        [sys.executable, "-m", "cli.main", "serve", "--no-bootstrap"],
        env=env,
        capture_output=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    assert b"expected redis://, rediss:// or postgresql://" in result.stderr
    assert b"hunter2" not in result.stderr + result.stdout


@pytest.mark.slow
def test_bootstrap_trains_the_missing_zoo_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from cli.serve import _bootstrap

    url = f"sqlite:///{tmp_path / 'models.db'}"
    _bootstrap(url, tmp_path, steps=60)
    # 60 steps pass no gate: the first run says which goals it cannot serve and how to fix it
    said = " ".join(capsys.readouterr().out.split())
    assert "no task network passed its gates for a0, a1" in said
    assert "coexist train task --goals a0,a1," in said
    with SqlModelStore(url) as store:
        names = [m.name for m in store.list_models(page_size=100).items]
        assert len(names) == 70
        assert store.resolve("particle/impact/c4@latest").lineage.parents
        versions = {name: store.resolve(f"{name}@latest").version for name in names}
    _bootstrap(url, tmp_path, steps=60)  # nothing missing: nothing trained again
    with SqlModelStore(url) as store:
        assert {name: store.resolve(f"{name}@latest").version for name in names} == versions
