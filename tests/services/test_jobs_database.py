"""Where the job API keeps its table: `COEXIST_JOBS_URL`, else the model store's SQL database,
else (a store backend without SQL, the tinyline test plugin's) `<data dir>/jobs.db`; the
subprocess gets the store's own URL either way, and a jobs URL's password is never shown."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from pydantic import SecretStr

from model_store.errors import InvalidArgument
from model_store.sql import SqlModelStore
from services.app import create_app
from services.jobs_api import _jobs_database, _open
from services.settings import Settings

TOKEN = "jobs-database-t0ken"


def _settings(data_dir: Path, jobs_url: str | None = None) -> Settings:
    return Settings(
        admin_token=SecretStr(TOKEN),
        data_dir=data_dir,
        grpc_enabled=False,
        jobs_url=None if jobs_url is None else SecretStr(jobs_url),
    )


def test_a_store_without_sql_keeps_its_jobs_beside_the_data(tmp_path: Path, tinyline: str) -> None:
    from tinyline.store import TinylineStore  # on sys.path while the fixture registers it

    with TinylineStore(f"tinyline://{tmp_path / 'models'}") as store:
        app = create_app(_settings(tmp_path / "data"), store=store)
        table, runner = _open(app)
        try:
            assert (tmp_path / "data" / "jobs.db").is_file()
            assert runner.store_url == f"tinyline://{tmp_path / 'models'}"
            listed = TestClient(app).get("/v1/jobs", headers={"Authorization": f"Bearer {TOKEN}"})
            assert listed.status_code == 200 and listed.json() == {"jobs": []}
        finally:
            table.close()
    assert not (tmp_path / "models" / "jobs.db").exists()


def test_a_sql_store_keeps_its_jobs_in_its_own_database(tmp_path: Path) -> None:
    with SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}") as store:
        url = _jobs_database(_settings(tmp_path / "data"), store)
    assert url.get_backend_name() == "sqlite" and url.database == str(tmp_path / "models.db")
    assert not (tmp_path / "data" / "jobs.db").exists()


def test_the_jobs_url_wins_and_its_password_stays_hidden(tmp_path: Path) -> None:
    settings = _settings(tmp_path, jobs_url="postgresql://jobs:s3cret-pw@db.internal/jobs")
    with SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}") as store:
        url = _jobs_database(settings, store)
    assert (url.host, url.database, url.password) == ("db.internal", "jobs", "s3cret-pw")
    assert "s3cret-pw" not in repr(settings) and "s3cret-pw" not in str(url)


def test_a_bad_jobs_url_is_named(tmp_path: Path) -> None:
    settings = _settings(tmp_path, jobs_url="mysql://u@h/db")
    with (
        SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}") as store,
        pytest.raises(InvalidArgument) as refused,
    ):
        _jobs_database(settings, store)
    assert refused.value.field == "jobs_url"
    assert str(refused.value).startswith("COEXIST_JOBS_URL: unsupported backend")
