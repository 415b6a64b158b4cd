"""benchmarks/catalogue.py: the synthetic catalogue keeps the particle goals first and names
every goal once, and a short real run steps a session on a catalogue of each size asked for
(the figures themselves are not asserted)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

from catalogue import catalogue  # noqa: E402

from envs.particle.goals import GOAL_IDS  # noqa: E402


def test_the_synthetic_catalogue_extends_the_particle_goals() -> None:
    goals = catalogue(350)
    assert len(goals) == len(set(goals)) == 350
    assert goals[: len(GOAL_IDS)] == GOAL_IDS
    assert catalogue(35) == GOAL_IDS


def test_a_short_run_prints_a_row_per_catalogue() -> None:
    done = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "catalogue.py"),
            "--goals",
            "35,40",
            "--steps",
            "25",
            "--rounds",
            "1",
        ],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    rows = [line for line in done.stdout.splitlines() if line.startswith("| ")]
    assert [row.split("|")[1].strip() for row in rows[1:]] == ["35", "40"]
    for row in rows[1:]:
        cells = [cell.strip() for cell in row.strip("|").split("|")]
        assert cells[1] == "0"  # no pruning asked for: τ = 0 and nothing pruned
        p50, p99, cpu = (float(cell) for cell in cells[2:5])
        assert 0 < p50 <= p99 and cpu > 0
        assert cells[5:] == ["-", "-", "-"]
