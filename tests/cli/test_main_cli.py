"""The `coexist` command itself: `--version` prints the VERSION file's version and exits 0."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_version_prints_the_version_file() -> None:
    answer = subprocess.run(
        [sys.executable, "-m", "cli.main", "--version"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert answer.returncode == 0, answer.stderr
    assert answer.stdout == f"coexist {(REPO / 'VERSION').read_text().strip()}\n"
