"""The acceptance test of the client distribution: build the `sdk/` wheel, install it
into a fresh virtual environment (no torch, FastAPI or SQLAlchemy there, nor any of the server's
packages), and run act (HTTP and gRPC), a session and a registry promote against a real
`coexist serve` (`sdk_install_script.py`)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import venv
from pathlib import Path

import pytest
from coexist_client import Client
from console_zoo import build_console_zoo
from live_serve import serving
from replica_cluster import ADMIN_TOKEN

REPO = Path(__file__).resolve().parents[2]
OBS = [0.1, 0.5, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]


@pytest.mark.slow
def test_the_sdk_wheel_works_alone_against_a_real_server(tmp_path: Path) -> None:
    source = tmp_path / "sdk"  # a copy: building writes build/ beside the sources
    shutil.copytree(REPO / "sdk", source, ignore=shutil.ignore_patterns("build", "*.egg-info"))
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path / "dist"),
            str(source),
        ],
        check=True,
        capture_output=True,
        timeout=300,
    )
    (wheel,) = (tmp_path / "dist").glob("coexist_client-*.whl")
    venv.create(tmp_path / "fresh", with_pip=True)
    python = tmp_path / "fresh" / "bin" / "python"
    subprocess.run(
        [str(python), "-m", "pip", "install", "-q", str(wheel)],
        check=True,
        capture_output=True,
        timeout=600,
    )
    folder = tmp_path / "server"
    with serving(folder, build_console_zoo(folder / "models.db")) as server:
        with Client(server.http_url) as client:  # before the script promotes a version 2
            want = client.act("particle", "a2", OBS, partners={1: "b3"}, seed=7)
        done = subprocess.run(
            [
                str(python),
                str(REPO / "tests" / "sdk" / "sdk_install_script.py"),
                server.http_url,
                server.grpc_target,
                ADMIN_TOKEN,
            ],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
            cwd=tmp_path,
        )
        assert done.returncode == 0, done.stderr[-3000:]
    got = json.loads(done.stdout)
    assert got["server_modules_found"] == []
    assert got["act_http"] == pytest.approx(list(want.probs), abs=1e-12)
    assert got["act_grpc"] == pytest.approx(list(want.probs), abs=1e-12)
    assert got["session"] == {"step": 1, "updates": 1}
    assert got["promoted"] == 2 and got["resolved"] == 2
