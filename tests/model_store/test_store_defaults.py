"""Default store location, engine URL handling and the code-version helper."""

from __future__ import annotations

from pathlib import Path

import pytest

from model_store.defaults import default_store_url, open_store
from model_store.errors import InvalidArgument
from model_store.lineage import code_version
from model_store.sql.engine import normalise_url


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
