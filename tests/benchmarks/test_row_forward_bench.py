"""benchmarks/row_forward.py: a short real run prints one table row per case, each with its hot
and cold medians (the figures themselves are not asserted)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from policy.row_forward import COMPILED

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.skipif(not COMPILED, reason="no compiled row forward on this machine")
def test_a_short_run_prints_every_case() -> None:
    script = ROOT / "benchmarks" / "row_forward.py"
    done = subprocess.run(
        [sys.executable, str(script), "--calls", "3"],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    rows = [line for line in done.stdout.splitlines() if line.startswith("| ") and "x" in line]
    cases = [row.split("|")[1].strip() for row in rows[1:]]  # after the header
    assert cases == ["35 x 1", "35 x 4", "1 x 1024", "4 x 256"]
    for row in rows[1:]:
        cells = [cell.strip() for cell in row.strip("|").split("|")]
        assert len(cells) == 6 and all(float(c) > 0 for c in cells[1:])
