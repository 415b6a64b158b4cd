"""`coexist serve` as a user runs it: with one worker REST sessions work end to end; with two the
create is refused (501, saying why) because a session's steps could reach the other worker, while
the gRPC Episode with an inferred partner still works (one stream stays on one worker)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest
from coexist_client import CoexistClient, CoexistError, GrpcCoexistClient
from serve_process import OBS, free_port, serve_command, wait_ready
from session_zoo import session_zoo_template


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_sessions_need_one_worker(
    tmp_path_factory: pytest.TempPathFactory, tmp_path: Path, workers: int
) -> None:
    http_port, grpc_port = free_port(), free_port()
    env = {**os.environ, "COEXIST_DEV_MODE": "1", "COEXIST_DATA_DIR": str(tmp_path)}
    env.pop("COEXIST_WORKERS", None)
    private = tmp_path / "models.db"  # the server may write (migrations): a private copy
    shutil.copy(session_zoo_template(tmp_path_factory), private)
    store_url = f"sqlite:///{private}"
    cmd = serve_command(store_url, http_port, grpc_port, "--workers", str(workers))
    process = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        url = f"http://127.0.0.1:{http_port}"
        wait_ready(url, process)
        with CoexistClient(url) as rest, GrpcCoexistClient(f"127.0.0.1:{grpc_port}") as grpc:
            if workers == 1:
                with rest.create_session("particle", "a2", partners={1: None}) as session:
                    session.step(OBS)
                    assert session.step(OBS, observed={1: 2}).beliefs[0].updates == 1
            else:
                with pytest.raises(CoexistError) as err:
                    rest.create_session("particle", "a2", partners={1: None})
                assert err.value.code == "unimplemented"
                assert "2 worker processes" in err.value.message
            assert rest.act("particle", "a2", OBS).probs  # stateless routes answer anyway
            with grpc.episode("particle", "a2", partners={1: None}) as episode:
                episode.act(OBS)
                assert episode.act(OBS, observed={1: 2}).beliefs[0].updates == 1
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
