"""benchmarks/capacity.py with `--replicas 2`: two `coexist serve` processes on one model store
and one Redis session store, every robot's steps alternating between them. A step that reached
a replica without the session would be a 404 and count as an error; the level must have none
and (nearly) every scheduled step done. The same with `--sticky` (each robot kept to one
replica, the robots spread over both). Also the flags it refuses."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "services"))

from session_backends import redis_url  # noqa: E402

CAPACITY = [sys.executable, str(ROOT / "benchmarks" / "capacity.py")]


def _rows(out: str) -> list[list[str]]:
    """The ladder's rows, `| coexist | sessions | steps | done | ... | held |` (ten cells; the
    summary's row has four)."""
    rows = [
        [cell.strip() for cell in line.strip().strip("|").split("|")]
        for line in out.splitlines()
        if line.startswith("| coexist | ")
    ]
    return [row for row in rows if len(row) == 10]


@pytest.mark.slow
@pytest.mark.redis
@pytest.mark.parametrize("sticky", [False, True], ids=["alternating", "sticky"])
def test_two_replicas_serve_every_robot_step_by_step(sticky: bool) -> None:
    with redis_url() as url:
        done = subprocess.run(
            [
                *CAPACITY,
                *("--replicas", "2", "--session-store", url),
                *("--sessions", "3", "--duration", "2", "--processes", "1"),
                *(["--sticky"] if sticky else []),
            ],
            capture_output=True,
            text=True,
            timeout=600,
        )
    assert done.returncode == 0, done.stderr[-2000:]
    said = "2 replica(s) of 1 worker(s)" + (", sticky" if sticky else "") + "; sessions in redis"
    assert said in done.stdout
    (row,) = [r for r in _rows(done.stdout) if r[1] == "3"]
    sessions, steps, errors = int(row[1]), int(row[2]), int(row[6])
    assert errors == 0, row
    assert steps >= 0.9 * sessions * 10 * 2, row  # 10 Hz for 2 s, each robot


@pytest.mark.parametrize(
    "flags, said",
    [
        (["--replicas", "2"], "needs --session-store"),
        (["--replicas", "0"], "at least 1"),
        (
            ["--replicas", "2", "--session-store", "redis://x", "--throughput"],
            "not with --replicas",
        ),
        (["--replicas", "2", "--session-store", "redis://x", "--servers", "ray"], "one worker"),
        (["--sticky"], "with --replicas > 1 only"),
    ],
)
def test_replicas_flags_refused_by_name(flags: list[str], said: str) -> None:
    done = subprocess.run([*CAPACITY, *flags], capture_output=True, text=True, timeout=120)
    assert done.returncode != 0
    assert said in done.stderr
