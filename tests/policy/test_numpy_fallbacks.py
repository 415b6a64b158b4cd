"""Without the compiled forward and belief step (no C compiler, a CPU without AVX2, or the A/B
switches), the engine and the sessions still give the answers their tests expect: the main
suite runs compiled, so these modules run again here with COEXIST_PYTHON_FORWARD=1 and
COEXIST_PYTHON_BELIEF=1 in a subprocess."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MODULES = [
    "tests/services/test_goal_likelihoods.py",
    "tests/services/test_sessions_prefetch.py",
    "tests/services/test_engine_fastpath.py",
    "tests/services/test_engine_groups.py",
    "tests/policy/test_goal_belief.py",
    "tests/policy/test_belief_fast_paths.py",
]


@pytest.mark.slow
def test_the_numpy_paths_pass_the_engine_and_session_tests() -> None:
    env = {**os.environ, "COEXIST_PYTHON_FORWARD": "1", "COEXIST_PYTHON_BELIEF": "1"}
    missing = [m for m in MODULES if not (ROOT / m).exists()]
    assert not missing, f"moved or renamed: {missing}"
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-x", *MODULES],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    # the switches took: the compiled parts' own tests were skipped
    check = (
        "import policy.row_forward as r, policy.belief_compiled as b; print(r.COMPILED, b.COMPILED)"
    )
    out = subprocess.run([sys.executable, "-c", check], env=env, capture_output=True, text=True)
    assert out.stdout.split() == ["False", "False"], out.stderr
