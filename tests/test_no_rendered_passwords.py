"""No module outside the tests renders a database URL together with its password.

`URL.render_as_string(hide_password=False)` makes a string that holds the password, one print,
log line or traceback away from a leak; coexist hands the password over apart instead
(docs/security.md, "The store's password"). A call is refused when it passes anything but the
literal `True` for `hide_password`, by keyword, by position or through `**options`, since a
variable can be False. Tests may still render their fixtures' URLs.

The modules are the Python files git lists as tracked or as new and not ignored, so the virtual
environment and build outputs don't count, and a module not committed yet does.
"""

from __future__ import annotations

import ast
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _may_render_password(call: ast.Call) -> bool:
    if not (isinstance(call.func, ast.Attribute) and call.func.attr == "render_as_string"):
        return False
    given = [*call.args[:1]]
    given += [k.value for k in call.keywords if k.arg in ("hide_password", None)]
    return any(not (isinstance(v, ast.Constant) and v.value is True) for v in given)


def _renders(source: str, name: str) -> list[str]:
    tree = ast.parse(source, name)
    return [
        f"{name}:{node.lineno}: {ast.unparse(node)}"
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and _may_render_password(node)
    ]


def _modules() -> list[str]:
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard", "*.py"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split("\0")
    # any `tests` folder (the examples' distributions have their own) holds tests, not modules
    return sorted(
        name
        for name in set(filter(None, listed))
        if "tests" not in Path(name).parts and (ROOT / name).is_file()
    )


def test_the_scan_catches_what_it_is_for() -> None:
    refused = [
        "url.render_as_string(hide_password=False)",
        "make_url(s).render_as_string(False)",
        "url.render_as_string(hide_password=show)",
        "url.render_as_string(**options)",
    ]
    allowed = [
        "url.render_as_string()",
        "url.render_as_string(hide_password=True)",
        "redact_url(url)",
        "url.render(hide_password=False)",
    ]
    assert all(_renders(code, "x.py") for code in refused)
    assert not [code for code in allowed if _renders(code, "x.py")]


def test_no_module_renders_a_url_with_its_password() -> None:
    modules = _modules()
    # the listing worked, and sees the modules that hand the store's URL to other processes
    assert {"model_store/sql/sql_store.py", "trainer/backends/once.py"} <= set(modules)
    assert not any(name.startswith(("tests/", ".venv/")) for name in modules)
    hits = [hit for name in modules for hit in _renders((ROOT / name).read_text(), name)]
    assert not hits, (
        'hand the password over apart (docs/security.md, "The store\'s password"):\n'
        + "\n".join(hits)
    )
