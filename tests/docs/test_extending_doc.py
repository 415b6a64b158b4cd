"""docs/extending.md: the console blocks marked `<!-- plugin steps -->` run as written, in one
bash session from the repository root, with three changes that keep the test from touching the
shared virtual environment or the machine: the example is installed into a folder of its own
(`pip install --target`, put on PYTHONPATH) instead of into the venv, `mktemp -d` is the test's
temporary folder, and the server's port 8000 is a free one. A failing step fails the test."""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from serve_process import free_port

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "extending.md"
MARK = "<!-- plugin steps -->"


def plugin_steps() -> list[str]:
    """The `$ ` lines of every console block right below the mark, in order."""
    lines = [line.strip() for line in PAGE.read_text().splitlines()]
    steps = []
    for k, line in enumerate(lines):
        if line != MARK:
            continue
        assert lines[k + 1] == "```console", f"extending.md:{k + 1}: a console block must follow"
        end = next(j for j in range(k + 2, len(lines)) if lines[j].startswith("```"))
        steps += [x.removeprefix("$ ") for x in lines[k + 2 : end] if x.startswith("$ ")]
    return steps


def test_the_steps_are_there() -> None:
    steps = plugin_steps()
    assert any(s.startswith("pip install") for s in steps)
    for command in ("coexist env check", "coexist train zoo", "coexist serve", "coexist run"):
        assert any(command in s for s in steps), command


@pytest.mark.slow
def test_the_plugin_steps_run_as_written(tmp_path: Path) -> None:
    port = str(free_port())
    site = tmp_path / "site"
    script = ["set -euo pipefail"]
    for step in plugin_steps():
        step = step.replace("$(mktemp -d)", str(tmp_path / "plugins"))
        step = step.replace(
            "pip install --no-deps", f"pip install --no-deps --no-build-isolation --target {site}"
        )
        step = re.sub(r"\b8000\b", port, step)
        shown = step.replace('"', "'")
        script += [f'echo ">>> $(date +%T) {shown}"', step]
    (tmp_path / "plugins").mkdir()
    env = {
        **os.environ,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
        "PYTHONPATH": str(site),
    }
    env.pop("COEXIST_STORE_URL", None)
    env.pop("COEXIST_DATA_DIR", None)
    process = subprocess.Popen(
        ["bash", "-c", "\n".join(script)],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # its background server goes with it
    )
    try:
        output, _ = process.communicate(timeout=600)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGTERM)
    assert process.returncode == 0, output[-6000:]
    assert "tinyline: all 9 checks passed" in output
    assert "agent_0 (ego)" in output  # coexist run's table
    assert "tinyline/task/c2" in output  # coexist models list, on the plugin's store
    assert "train task" in output  # the store's record of the processes that opened it
