"""benchmarks/row_forward.py: a short real run prints one table row per case and vector width the
CPU has, each with its hot and cold medians (the figures themselves are not asserted)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from policy.row_forward import COMPILED, vector_widths

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
    cells = [[cell.strip() for cell in row.strip("|").split("|")] for row in rows[1:]]
    widths = vector_widths()
    cases = ["35 x 1", "35 x 4", "1 x 1024", "4 x 256"]
    assert [(row[0], int(row[1])) for row in cells] == [(c, w) for c in cases for w in widths]
    for row in cells:
        assert len(row) == 7 and all(float(c) > 0 for c in row[2:5])  # times and their ratio
        assert all(float(c) >= 0 for c in row[5:])  # rates, one decimal: a tiny one prints 0.0
