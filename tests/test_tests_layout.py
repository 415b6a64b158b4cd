"""`tests/` mirrors the source tree folder for folder: every folder of Python source
has a folder of tests at the same path, so the tests of a module are found where it lives.

The SDK's sources live in `sdk/coexist_client/` (its own distribution) and its tests in
`tests/sdk/`. Generated code (`gen/` folders) is tested through what uses it, and Alembic's
migration scripts through `tests/model_store/sql/test_store_migrations.py`, which checks that
they build exactly the schema the ORM maps.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# top-level folders that hold no package of ours (examples/: separate distributions, each with
# its own tests, run by tests/envs/test_mpe2_landmarks_example.py)
NOT_SOURCE = ("tests", "docs", "scripts", "examples")
NO_MIRROR = ("model_store/migrations",)  # Alembic's scripts (module docstring)


def _source_folders() -> set[str]:
    """The folders of the tracked Python files (as git lists them, so build outputs don't
    count), SDK folders under their test name (`sdk/coexist_client/x` -> `sdk/x`)."""
    listed = subprocess.run(
        ["git", "ls-files", "*.py"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    folders = set()
    for name in listed:
        folder = Path(name).parent.as_posix()
        if folder == "." or folder.split("/")[0] in NOT_SOURCE or "/gen" in f"/{folder}":
            continue
        if folder.startswith(NO_MIRROR):
            continue
        folders.add(folder.replace("sdk/coexist_client", "sdk", 1))
    return folders


def test_every_source_folder_has_a_test_folder() -> None:
    folders = _source_folders()
    assert {"cli", "services/engine", "model_store/sql", "sdk"} <= folders  # the walk sees them
    missing = sorted(f for f in folders if not (ROOT / "tests" / f).is_dir())
    assert not missing, f"source folders without tests/<folder>: {missing}"
