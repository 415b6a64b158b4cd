"""examples/mpe2_landmarks, the third environment, from outside coexist: MPE2's physics as a
plugin distribution. Installed as a user installs it (with mpe2 from the package index, into a
folder of its own put on PYTHONPATH), its own tests pass, `coexist env check` passes, and
`coexist train task` trains and registers its networks with coexist's generic trainer."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "mpe2_landmarks"

pytestmark = pytest.mark.slow


def test_the_example_installs_checks_and_trains(tmp_path: Path) -> None:
    site = tmp_path / "site"
    shutil.copytree(EXAMPLE, tmp_path / "src", ignore=shutil.ignore_patterns("build", "*.egg-*"))
    pip = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(site)]
    fetched = subprocess.run([*pip, "mpe2>=1.1"], capture_output=True, text=True, timeout=300)
    if fetched.returncode != 0:
        pytest.skip(f"mpe2 could not be installed from the package index: {fetched.stderr[-500:]}")
    subprocess.run([*pip, "--no-build-isolation", str(tmp_path / "src")], check=True, timeout=300)
    env = {
        **os.environ,
        "PYTHONPATH": str(site),
        "COEXIST_STORE_URL": f"sqlite:///{tmp_path / 'models.db'}",
    }

    def run(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600
        )

    own = run("-m", "pytest", "-q", "-p", "no:cacheprovider", "tests", cwd=tmp_path / "src")
    assert own.returncode == 0, own.stdout[-3000:] + own.stderr[-2000:]
    checked = run("-m", "cli.main", "env", "check", "mpe2_landmarks", "--episodes", "1")
    assert checked.returncode == 0, checked.stdout + checked.stderr
    trained = run(
        "-m", "cli.main", "train", "task", "--env", "mpe2_landmarks", "--goals", "l0",
        "--steps", "300", "--run-dir", str(tmp_path / "runs"),
    )  # fmt: skip
    # 300 steps may not pass the gate (exit 4): the networks are trained and registered either way
    assert trained.returncode in (0, 4), trained.stdout[-3000:] + trained.stderr[-3000:]
    assert "mpe2_landmarks" in trained.stdout or "l0" in trained.stdout
