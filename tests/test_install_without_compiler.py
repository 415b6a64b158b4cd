"""`pip install .` needs no C compiler: a wheel of the repository builds with `CC` pointing at a
compiler that does not exist (setup.py's two C kernels are optional and are left out), holds
the numba kernels' sources, and the blend, the belief step and the forward run from it (the
forward on its numpy reference, the only kernel without its C there)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

CHECK = """
import sys

# the wheel's copy, not this checkout's editable install (its finder comes first otherwise)
sys.meta_path = [f for f in sys.meta_path if "editable" not in str(getattr(f, "__module__", ""))]
import numpy as np
import policy
from policy.blend import blend
from policy.belief import BeliefConfig, PreparedUpdate
from policy.row_forward import COMPILED, row_forward

assert policy.__file__.startswith(sys.argv[1]), policy.__file__
assert not COMPILED  # no C forward in this wheel
got = blend("aail_bounded", np.zeros((1, 3)), np.ones((1, 1, 3)), 0.5, regret_bound=0.1)
assert abs(got.probs_BA.sum() - 1.0) < 1e-12
update = PreparedUpdate(np.log(np.full((1, 4), 0.25)), BeliefConfig())
assert update(np.log(np.full((1, 4), 0.25)), np.log(np.full((1, 4), 0.25))).shape == (1, 4)
layers = [(np.ones((1, 2, 3), np.float32), np.zeros((1, 1, 3), np.float32))]
assert row_forward(np.ones((1, 1, 2), np.float32), layers, 0, 1, "relu").tolist() == [[[2, 2, 2]]]
print("ok")
"""


@pytest.mark.slow
def test_a_wheel_builds_and_runs_without_a_c_compiler(tmp_path: Path) -> None:
    listed = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    source = tmp_path / "source"
    for name in listed:  # the working tree as git sees it: no build outputs, no .so files
        if (ROOT / name).is_file():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, source / name)
    missing = "/nonexistent/cc"
    env = {**os.environ, "CC": missing, "CXX": missing, "LDSHARED": f"{missing} -shared"}
    wheels = tmp_path / "wheels"
    offline = ("--no-deps", "--no-build-isolation", "--no-index")
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", ".", *offline, "-w", str(wheels)],
        cwd=source,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    (wheel,) = wheels.glob("coexist-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        metadata = archive.read(next(n for n in names if n.endswith(".dist-info/METADATA")))
        archive.extractall(tmp_path / "installed")
    assert not [n for n in names if n.endswith((".so", ".pyd"))]  # nothing compiled went in
    assert {"policy/blend_kernel.py", "policy/belief_kernel.py"} <= set(names)
    assert b"Requires-Dist: numba" in metadata
    run_env = {
        **os.environ,
        "PYTHONPATH": str(tmp_path / "installed"),
        "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache"),
    }
    ran = subprocess.run(
        [sys.executable, "-c", CHECK, str(tmp_path / "installed")],
        cwd=tmp_path,
        env=run_env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert ran.returncode == 0 and ran.stdout.strip() == "ok", ran.stderr[-3000:]
