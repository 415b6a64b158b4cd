"""Every code block of the README and docs/ marked `<!-- runnable -->` runs as written against a
real `coexist serve` (over the console zoo: every particle and kitchen goal has its networks).

Python blocks run in a fresh interpreter; console blocks run their `$ ` lines in bash. The only
change to a block is the server's address: `127.0.0.1:8000` / `localhost:8000` become the test
server's REST port and `:50051` its gRPC port. A block fails the test by exiting non-zero."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from console_zoo import build_console_zoo
from live_serve import serving
from replica_cluster import Server

ROOT = Path(__file__).resolve().parents[2]
MARK = "<!-- runnable -->"
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w+)\s*$")


def runnable_blocks(page: Path) -> list[tuple[str, str, int]]:
    """(language, code, line number) of each block of `page` that follows the mark."""
    lines = page.read_text().splitlines()
    blocks = []
    for k, line in enumerate(lines):
        if line.strip() != MARK:
            continue
        opening = FENCE.match(lines[k + 1]) if k + 1 < len(lines) else None
        assert opening, f"{page.name}:{k + 1}: the mark must stand right above a fenced block"
        end = next(j for j in range(k + 2, len(lines)) if lines[j].startswith("```"))
        blocks.append((opening.group(1), "\n".join(lines[k + 2 : end]) + "\n", k + 1))
    return blocks


BLOCKS = [(page, *block) for page in PAGES for block in runnable_blocks(page)]


def test_the_marked_blocks_are_there() -> None:
    """Removing the marks must not pass this test silently: the README's two SDK examples and
    docs/client.md's (SDK, both remote policies, `coexist run`) are marked."""
    counted = {page.name: sum(1 for b in BLOCKS if b[0] == page) for page in PAGES}
    assert counted["README.md"] >= 2 and counted["client.md"] >= 4, counted
    assert {language for _, language, _, _ in BLOCKS} <= {"python", "console", "bash"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    folder = tmp_path_factory.mktemp("runnable-docs")
    with serving(folder, build_console_zoo(folder / "models.db")) as running:
        yield running


def _addressed(code: str, server: Server) -> str:
    http_port = server.http_url.rsplit(":", 1)[1]
    grpc_port = server.grpc_target.rsplit(":", 1)[1]
    for host in ("127.0.0.1", "localhost"):
        code = code.replace(f"{host}:8000", f"{host}:{http_port}")
        code = code.replace(f"{host}:50051", f"{host}:{grpc_port}")
    return code


def _commands(console: str) -> str:
    """The `$ ` lines of a console block (a line ending in `\\` goes on), without the prompt."""
    commands, going_on = [], False
    for line in console.splitlines():
        if line.startswith("$ ") or going_on:
            commands.append(line.removeprefix("$ "))
            going_on = line.endswith("\\")
    return "set -e\n" + "\n".join(commands) + "\n"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("page", "language", "code", "line"),
    BLOCKS,
    ids=[f"{page.name}:{line}" for page, _, _, line in BLOCKS],
)
def test_the_block_runs_as_written(
    server: Server, page: Path, language: str, code: str, line: int, tmp_path: Path
) -> None:
    env = {k: v for k, v in os.environ.items() if not k.startswith("COEXIST_")}
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"  # `coexist`
    env["COLUMNS"] = "200"
    code = _addressed(code, server)
    python = [sys.executable, "-c", code]
    argv = python if language == "python" else ["bash", "-c", _commands(code)]
    done = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{page.name}:{line}\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
