"""Default store location, engine URL handling and the code-version helper."""

from __future__ import annotations

from importlib.metadata import EntryPoint
from pathlib import Path

import pytest
from sqlalchemy.engine import make_url

from model_store import defaults
from model_store.defaults import (
    check_store_url,
    default_store_url,
    open_store,
    store_factory,
    store_schemes,
)
from model_store.errors import InvalidArgument
from model_store.lineage import code_version
from model_store.sql import SqlModelStore
from model_store.sql.engine import normalise_url, without_password


def test_default_url_prefers_env_then_data_dir(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setenv("COEXIST_STORE_URL", "postgresql://u@db/x")
    assert default_store_url() == "postgresql://u@db/x"
    monkeypatch.delenv("COEXIST_STORE_URL")
    monkeypatch.setenv("COEXIST_DATA_DIR", str(tmp_path / "data"))
    assert default_store_url() == f"sqlite:///{tmp_path / 'data' / 'models.db'}"
    assert (tmp_path / "data").is_dir()
    monkeypatch.delenv("COEXIST_DATA_DIR")
    monkeypatch.chdir(tmp_path)
    assert default_store_url() == "sqlite:///.coexist/models.db"
    with pytest.raises(InvalidArgument, match="no SQLite database"):
        open_store()  # a reader: nothing there yet, and nothing created
    with open_store(create=True) as store:
        assert store.list_models().items == ()
    assert (tmp_path / ".coexist" / "models.db").is_file()


def test_urls_are_normalised_to_psycopg_and_bad_ones_refused() -> None:
    assert normalise_url("postgresql://u@h:5/d").drivername == "postgresql+psycopg"
    assert normalise_url("postgres://u@h/d").drivername == "postgresql+psycopg"
    assert normalise_url("postgresql+psycopg://u@h/d").drivername == "postgresql+psycopg"
    assert normalise_url("sqlite:///x.db").drivername == "sqlite"
    for bad in ("mysql://u@h/d", "not a url"):
        with pytest.raises(InvalidArgument) as err:
            normalise_url(bad)
        assert err.value.field == "store_url"
    with pytest.raises(InvalidArgument, match="in-memory"):
        open_store("sqlite://")


def test_code_version_is_a_non_empty_string() -> None:
    version = code_version()
    assert isinstance(version, str) and version


def test_the_scheme_picks_the_backend(tmp_path: Path) -> None:
    """coexist's SQL store under its schemes (a dialect's `+driver` falls back to the scheme);
    an unknown scheme or none is `InvalidArgument` on `store_url` naming the installed ones."""
    assert {"sqlite", "postgresql", "postgres"} <= set(store_schemes())
    assert store_factory("sqlite:///x.db") is SqlModelStore
    assert store_factory("postgresql+psycopg://u@h/d") is SqlModelStore
    with open_store(f"sqlite:///{tmp_path / 'm.db'}", create=True) as store:
        assert isinstance(store, SqlModelStore)
        assert store.reopen_url() == f"sqlite:///{tmp_path / 'm.db'}"
    for bad, shown in (("nosuch://x", "scheme 'nosuch'"), ("models.db", "no scheme")):
        with pytest.raises(InvalidArgument) as err:
            open_store(bad)
        assert err.value.field == "store_url"
        assert shown in str(err.value) and "installed: " in str(err.value)
        assert "postgresql" in str(err.value)


def test_a_backend_that_fails_to_load_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    broken = [EntryPoint("broken", "no_such_backend:open", defaults.ENTRY_POINT_GROUP)]
    monkeypatch.setattr(defaults, "entry_points", lambda group: broken)
    with pytest.raises(InvalidArgument, match=r"scheme 'broken' \(no_such_backend:open\) failed"):
        open_store("broken://x")


def test_check_store_url_names_what_opening_would_refuse(tmp_path: Path) -> None:
    with pytest.raises(InvalidArgument, match="no SQLite database"):
        check_store_url(f"sqlite:///{tmp_path / 'missing.db'}", create=False)
    check_store_url(f"sqlite:///{tmp_path / 'missing.db'}", create=True)
    with pytest.raises(InvalidArgument, match="scheme 'nosuch'"):
        check_store_url("nosuch://x", create=True)


def test_a_url_object_keeps_its_password_and_another_process_gets_it_apart(
    tmp_path: Path,
) -> None:
    """A URL object is taken as it is (`str` would mask its password as `***`, and the driver
    would send that); what another process gets is the URL without the password, and the
    password apart (`reopen_password`)."""
    url = make_url("postgresql://u:s3cret@h:5432/d?sslmode=require")
    parsed = normalise_url(url)
    assert parsed.password == "s3cret" and parsed.drivername == "postgresql+psycopg"
    assert store_factory(parsed) is SqlModelStore
    bare = without_password(parsed)
    assert bare.password is None and bare.query == parsed.query
    assert bare.render_as_string() == "postgresql+psycopg://u@h:5432/d?sslmode=require"
    with open_store(make_url(f"sqlite:///{tmp_path / 'm.db'}"), create=True) as store:
        assert store.reopen_url() == f"sqlite:///{tmp_path / 'm.db'}"
        assert store.reopen_password() is None
