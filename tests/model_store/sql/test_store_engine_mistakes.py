"""Mistakes in a store URL are named, not swallowed: a SQLite file that does not exist is an
error naming its path unless creation is asked for, and a PostgreSQL URL whose driver is not
installed names the extra to install (in a real process, without a traceback)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from model_store.defaults import open_store
from model_store.errors import InvalidArgument
from model_store.sql import SqlModelStore

REPO = Path(__file__).resolve().parents[3]


def test_a_missing_sqlite_file_is_an_error_naming_it_unless_creation_is_asked(
    tmp_path: Path,
) -> None:
    typo = tmp_path / "modles.db"
    with pytest.raises(InvalidArgument) as err:
        open_store(f"sqlite:///{typo}")
    assert err.value.field == "store_url"
    assert f"no SQLite database at '{typo}'" in str(err.value)
    assert "the file does not exist" in str(err.value)
    assert not typo.exists()  # nothing was created in its place
    with open_store(f"sqlite:///{typo}", create=True) as store:
        assert store.list_models().items == ()
    with open_store(f"sqlite:///{typo}") as store:  # now it exists: opened as it is
        assert store.list_models().items == ()
    with pytest.raises(InvalidArgument, match="no SQLite database"):
        SqlModelStore(f"sqlite:///{tmp_path / 'other.db'}", create=False)


def _shadow_driver(folder: Path) -> dict[str, str]:
    """An environment whose `import psycopg` fails as it does where the driver is not
    installed (a package of that name that raises ModuleNotFoundError first on the path)."""
    package = folder / "psycopg"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text(
        "raise ModuleNotFoundError(\"No module named 'psycopg'\", name='psycopg')\n"
    )
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(folder), str(REPO)])
    env.pop("COEXIST_STORE_URL", None)
    return env


def test_a_postgresql_url_without_its_driver_names_the_extra(tmp_path: Path) -> None:
    env = _shadow_driver(tmp_path / "site")
    url = "postgresql://postgres@127.0.0.1:5432/nowhere"
    listed = subprocess.run(
        [sys.executable, "-m", "cli.main", "models", "list", "--store-url", url],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert listed.returncode == 2, listed.stderr
    assert "PostgreSQL driver (psycopg) is not installed" in listed.stderr
    assert "pip install 'coexist[postgres]'" in listed.stderr
    assert "Traceback" not in listed.stderr + listed.stdout
    served = subprocess.run(
        [sys.executable, "-m", "cli.main", "serve", "--store-url", url, "--no-bootstrap"],
        env={**env, "COEXIST_DEV_MODE": "1"},
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert served.returncode == 2, served.stderr
    assert "pip install 'coexist[postgres]'" in served.stderr
    assert "Traceback" not in served.stderr + served.stdout
