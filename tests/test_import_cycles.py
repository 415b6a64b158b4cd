"""No import cycles among the project's modules, and no environment named outside its folder.

Every `import` statement counts, at module level or inside a function (a lazy import only
hides a cycle), except those under `if TYPE_CHECKING:` (annotations only, never run).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("trainer", "evaluation", "policy", "envs", "model_store", "services", "cli")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path, known: set[str]) -> set[str]:
    """The project modules `path` imports (a package's `__init__` for `from pkg import x`)."""
    tree = ast.parse(path.read_text(), str(path))
    skipped: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skipped.update(id(n) for child in node.body for n in ast.walk(child))
    found = set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [f"{node.module}.{a.name}" for a in node.names] + [node.module]
        else:
            continue
        for name in names:
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name:
                found.add(name)
    return found


def _graph() -> dict[str, set[str]]:
    files = [f for pkg in PACKAGES for f in (ROOT / pkg).rglob("*.py") if "_pb2" not in f.name]
    known = {_module_name(f) for f in files}
    graph = {}
    for f in files:
        name = _module_name(f)
        # importing a.b.c runs a/__init__ and a/b/__init__ first: not an edge of a.b.c's own
        graph[name] = {m for m in _imports(f, known) if m != name and not name.startswith(m + ".")}
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


@pytest.mark.parametrize("package", ["trainer", "evaluation"])
def test_no_import_cycle(package: str) -> None:
    graph = _graph()
    within = {
        m: {d for d in deps if d.split(".")[0] == package}
        for m, deps in graph.items()
        if m.split(".")[0] == package
    }
    assert _cycle(within) is None, " -> ".join(_cycle(within) or [])


def test_the_cycle_finder_finds_one() -> None:
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None


def test_the_trainer_names_no_environment_outside_its_folders() -> None:
    """`trainer/` outside `trainer/<env>/` neither imports an environment's package nor tests a
    name or a type against one (`trainer.plugins.env_trainer` finds a trainer through the
    environment's registration)."""
    envs = [p.name for p in (ROOT / "envs").iterdir() if (p / "__init__.py").exists()]
    pattern = re.compile(rf"envs\.({'|'.join(envs)})\b|==\s*[\"']({'|'.join(envs)})[\"']")
    offenders = []
    for f in (ROOT / "trainer").rglob("*.py"):
        if f.parent.name in envs:
            continue
        for n, line in enumerate(f.read_text().splitlines(), 1):
            if pattern.search(line) or re.search(r"isinstance\([^)]*(Cooking|Particle)", line):
                offenders.append(f"{f.relative_to(ROOT)}:{n}: {line.strip()}")
    assert offenders == []


def test_the_evaluation_and_its_command_test_no_environment_or_suite_name() -> None:
    """`evaluation/`'s shared modules and `cli/evaluate.py` neither compare a name with an
    environment's or a suite's nor test a type against an environment's: the CLI finds a suite
    through `evaluation.suites` (entry points), and each suite lives in its own folder."""
    envs = [p.name for p in (ROOT / "envs").iterdir() if (p / "__init__.py").exists()]
    suites = [p.parent.name for p in (ROOT / "evaluation").glob("*/command.py")]
    names = "|".join(envs + suites)
    pattern = re.compile(rf"[=!]=\s*[\"']({names})[\"']|[\"']({names})[\"']\s*[=!]=")
    files = [*(ROOT / "evaluation").glob("*.py"), ROOT / "cli" / "evaluate.py"]
    offenders = []
    for f in files:
        for n, line in enumerate(f.read_text().splitlines(), 1):
            if pattern.search(line) or re.search(r"isinstance\([^)]*(Cooking|Particle)", line):
                offenders.append(f"{f.relative_to(ROOT)}:{n}: {line.strip()}")
    assert suites and offenders == []
