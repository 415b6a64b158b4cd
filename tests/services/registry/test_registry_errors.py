"""The registry REST API on bad requests: auth, 404/409/413/415/422 naming the field, a
tampered artifact (502), a vanished database (503), and the default-token refusal."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from pydantic import SecretStr
from sqlalchemy import create_engine, text

from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_weights
from services.app import create_app
from services.settings import InsecureSettings, Settings

TOKEN = "s3cret-admin-token-0123"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
BASE = "/v1/registry"
NAME = "particle/task/a3"
SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
MODEL = {
    "name": NAME,
    "env": "particle",
    "kind": "task",
    "goals": ["a3"],
    "obs_dim": 8,
    "n_actions": 5,
}


def _client(tmp_path: Path, **settings) -> tuple[TestClient, SqlModelStore]:
    store = SqlModelStore(f"sqlite:///{tmp_path / 'db' / 'models.db'}", max_artifact_bytes=4096)
    app = create_app(
        Settings(admin_token=SecretStr(TOKEN), max_artifact_bytes=4096, **settings), store=store
    )
    return TestClient(app), store


@pytest.fixture
def client(tmp_path: Path):
    client, store = _client(tmp_path)
    assert client.post(f"{BASE}/models", json=MODEL, headers=AUTH).status_code == 201
    yield client
    store.close()


def _error(response, status: int, field: str | None = None) -> dict:
    assert response.status_code == status, response.text
    assert response.headers["content-type"] == "application/problem+json"  # RFC 9457
    error = response.json()
    assert set(error) >= {"type", "title", "status", "detail", "code", "field"} and error["detail"]
    path = response.request.url.raw_path.decode().partition("?")[0]  # percent-encoded
    assert error["status"] == status and error["instance"] == path
    if field is not None:
        assert error["field"] == field, error
    return error


def _upload(client: TestClient, *, weights=None, spec=SPEC, headers=AUTH, **files):
    parts = {"weights": ("w.safetensors", qnet_weights(SPEC) if weights is None else weights)}
    parts.update(files)
    data = {"spec": spec if isinstance(spec, str) else json.dumps(spec)}
    return client.post(f"{BASE}/models/{NAME}/-/versions", files=parts, data=data, headers=headers)


def test_writes_need_the_admin_token(client: TestClient) -> None:
    other = {**MODEL, "name": "particle/task/b1"}
    missing = client.post(f"{BASE}/models", json=other)
    assert _error(missing, 401)["code"] == "unauthorized"
    assert missing.headers["www-authenticate"] == "Bearer"
    _error(client.post(f"{BASE}/models", json=other, headers={"Authorization": "Bearer nope"}), 403)
    _error(client.post(f"{BASE}/models", json=other, headers={"Authorization": "Basic x"}), 401)
    _error(_upload(client, headers={}), 401)
    _error(client.delete(f"{BASE}/models/{NAME}"), 401)
    assert client.get(f"{BASE}/models").status_code == 200  # reads are open by default


def test_read_token_when_required(tmp_path: Path) -> None:
    client, store = _client(tmp_path, read_token="reader-token-0123456")
    _error(client.get(f"{BASE}/models"), 401)
    _error(client.get(f"{BASE}/changes", headers={"Authorization": "Bearer wrong"}), 403)
    assert client.get(
        f"{BASE}/models", headers={"Authorization": "Bearer reader-token-0123456"}
    ).is_success
    assert client.get(f"{BASE}/models", headers=AUTH).is_success  # the admin token reads too
    reader_write = client.post(
        f"{BASE}/models", json=MODEL, headers={"Authorization": "Bearer reader-token-0123456"}
    )
    _error(reader_write, 403)
    store.close()
    client, store = _client(tmp_path, require_read_token=True)
    _error(client.get(f"{BASE}/models"), 401)
    assert client.get(f"{BASE}/models", headers=AUTH).is_success
    store.close()


def test_not_found_and_conflict_name_what(client: TestClient) -> None:
    assert _error(client.get(f"{BASE}/models/particle/task/zz"), 404, "name")["code"] == "not_found"
    _error(client.get(f"{BASE}/models/{NAME}/-/versions/3"), 404, "version")
    _error(client.get(f"{BASE}/models/{NAME}/-/versions/3/weights"), 404, "version")
    _error(client.get(f"{BASE}/resolve", params={"ref": f"{NAME}@production"}), 404, "alias")
    _error(
        client.put(f"{BASE}/models/{NAME}/-/aliases/production", json={"version": 9}, headers=AUTH),
        404,
        "version",
    )
    _error(client.delete(f"{BASE}/models/{NAME}/-/aliases/production", headers=AUTH), 404, "alias")
    assert (
        _error(client.post(f"{BASE}/models", json=MODEL, headers=AUTH), 409, "name")["code"]
        == "already_exists"
    )
    assert _upload(client).status_code == 201
    _error(client.post(f"{BASE}/models/{NAME}/-/versions/1/archive", headers=AUTH), 409, "version")
    _error(client.get(f"{BASE}/nothing-here"), 404)


def test_validation_errors_name_the_field(client: TestClient) -> None:
    _error(client.get(f"{BASE}/models", params={"page_size": 0}), 422, "page_size")
    _error(client.get(f"{BASE}/models", params={"page_token": "garbage"}), 422, "page_token")
    _error(client.get(f"{BASE}/models", params={"kind": "policy"}), 422, "kind")
    bad_model = client.post(f"{BASE}/models", json={**MODEL, "obs_dim": -1}, headers=AUTH)
    _error(bad_model, 422, "obs_dim")
    bad_name = client.post(f"{BASE}/models", json={**MODEL, "name": "a/-/b"}, headers=AUTH)
    _error(bad_name, 422, "name")
    _error(client.get(f"{BASE}/models/{NAME}/-/versions/0"), 422, "version")
    _error(
        client.put(f"{BASE}/models/{NAME}/-/aliases/Prod!", json={"version": 1}, headers=AUTH),
        422,
        "alias",
    )
    _error(client.get(f"{BASE}/events", params={"since": -1}), 422, "since")
    # NUL, which PostgreSQL's text type cannot hold (it was a 503 there): refused on any backend
    _error(client.get(f"{BASE}/models", params={"env": "a\x00"}), 422, "env")
    _error(client.get(f"{BASE}/models", params={"tag": "k=\x00"}), 422, "tag")
    _error(client.get(f"{BASE}/models/particle%00/task/a3"), 404, "name")
    lone = json.dumps({**MODEL, "description": "x"}).replace('"x"', '"x\\ud800"')
    headers = {**AUTH, "content-type": "application/json"}
    _error(client.post(f"{BASE}/models", content=lone, headers=headers), 422, "body")


@pytest.mark.parametrize(
    ("weights", "spec", "field"),
    [
        (qnet_weights(SPEC)[:100], SPEC, "weights"),
        (qnet_weights(qnet_spec(hidden=(8,))), SPEC, "weights"),
        (qnet_weights(SPEC), qnet_spec(obs_dim=9, hidden=(16,)), "spec.obs_dim"),
        (qnet_weights(SPEC), "{not json", "spec"),
        (qnet_weights(SPEC), {**SPEC, "dtype": "int8"}, "spec"),
    ],
)
def test_bad_uploads_are_422_and_leave_nothing(client: TestClient, weights, spec, field) -> None:
    before = client.get(f"{BASE}/changes").json()["token"]
    _error(_upload(client, weights=weights, spec=spec), 422, field)
    assert client.get(f"{BASE}/changes").json()["token"] == before
    assert client.get(f"{BASE}/models/{NAME}").json()["versions"] == []


def test_upload_shape_errors(client: TestClient) -> None:
    _error(_upload(client, weights=b"x" * 5000), 413, "weights")
    no_weights = client.post(
        f"{BASE}/models/{NAME}/-/versions",
        data={"spec": json.dumps(SPEC)},
        files={"other": ("x", b"1")},
        headers=AUTH,
    )
    _error(no_weights, 422, "weights")
    _error(_upload(client, lineage=(None, b'{"seed": "x"}')), 422, "lineage.seed")
    # a lone surrogate escape: json.loads takes it, no UTF-8 encoder can write it (was a 500)
    lone = (None, b'{"registered_by": "x\\ud800"}')
    _error(_upload(client, lineage=lone), 422, "lineage")
    as_json = client.post(f"{BASE}/models/{NAME}/-/versions", json={"spec": SPEC}, headers=AUTH)
    _error(as_json, 415)
    truncated = client.post(
        f"{BASE}/models/{NAME}/-/versions",
        content=b'--xyz\r\nContent-Disposition: form-data; name="spec"\r\n\r\n{}',
        headers={**AUTH, "Content-Type": "multipart/form-data; boundary=xyz"},
    )
    _error(truncated, 422, "body")
    huge = client.post(
        f"{BASE}/models/{NAME}/-/versions",
        content=b"0" * (4096 + (1 << 20) + 1),
        headers={**AUTH, "Content-Type": "multipart/form-data; boundary=xyz"},
    )
    _error(huge, 413, "weights")


def test_tampered_weights_are_502_not_served(tmp_path: Path, client: TestClient) -> None:
    assert _upload(client).status_code == 201
    engine = create_engine(f"sqlite:///{tmp_path / 'db' / 'models.db'}")
    with engine.begin() as conn:
        conn.execute(text("UPDATE model_versions SET weights = :w"), {"w": b"tampered"})
    engine.dispose()
    assert (
        _error(client.get(f"{BASE}/models/{NAME}/-/versions/1/weights"), 502)["code"]
        == "checksum_mismatch"
    )


def test_vanished_database_is_503(tmp_path: Path, client: TestClient) -> None:
    shutil.rmtree(tmp_path / "db")
    for response in (
        client.get(f"{BASE}/models"),
        client.get(f"{BASE}/changes"),
        _upload(client),
        client.get(f"{BASE}/models/{NAME}"),
    ):
        assert _error(response, 503)["code"] == "store_unavailable"
        assert "unavailable" in response.json()["detail"]


def test_default_token_refused_outside_dev_mode(tmp_path: Path) -> None:
    with pytest.raises(InsecureSettings, match="COEXIST_ADMIN_TOKEN"):
        create_app(Settings())
    with pytest.raises(InsecureSettings):
        create_app(Settings(admin_token=SecretStr("")))
    dev = create_app(
        Settings(
            dev_mode=True,
            grpc_port=0,
            store_url=f"sqlite:///{tmp_path / 'dev.db'}",
            create_store=True,  # a new file: creation asked for
        )
    )
    with TestClient(dev) as client:  # the lifespan opens (and closes) the store from settings
        assert client.get(f"{BASE}/models").json() == {"models": [], "next_page_token": None}
        created = client.post(
            f"{BASE}/models", json=MODEL, headers={"Authorization": "Bearer dev-token"}
        )
        assert created.status_code == 201


def test_settings_come_from_the_environment(monkeypatch, tmp_path: Path) -> None:
    from services.settings import get_settings

    monkeypatch.setenv("COEXIST_ADMIN_TOKEN", "from-env-token-0123456")
    monkeypatch.setenv("COEXIST_DATA_DIR", str(tmp_path / "d"))
    monkeypatch.setenv("COEXIST_REQUIRE_READ_TOKEN", "true")
    get_settings.cache_clear()
    try:
        settings = get_settings()
        assert settings.admin_token.get_secret_value() == "from-env-token-0123456"
        assert settings.reads_need_token and not settings.dev_mode
        assert settings.resolved_store_url() == f"sqlite:///{tmp_path / 'd' / 'models.db'}"
        assert get_settings() is settings
    finally:
        get_settings.cache_clear()


def test_huge_version_number_is_a_4xx_not_a_500(client) -> None:
    response = client.get("/v1/registry/models/particle/task/a3/-/versions/99999999999999999999999")
    _error(response, 422)


@pytest.mark.parametrize(
    ("curve", "field"),
    [
        ({"steps": [0, 10], "mean_return": [1.0, "NaN"]}, "mean_return[1]"),
        ({"steps": [0, 10], "mean_return": [1.0, None]}, "mean_return[1]"),
        ({"steps": [0, 10], "loss": [0.5, {"x": 1}]}, "loss[1]"),
        ({"steps": [0, "ten"], "loss": [0.5, 0.4]}, "steps[1]"),
        ({"steps": [0, 10], "loss": [0.5]}, None),
        ("not a curve", None),
    ],
)
def test_a_training_curve_of_anything_but_finite_numbers_is_refused(
    client: TestClient, curve: object, field: str | None
) -> None:
    """The console draws `metrics.training_curve`: a string or NaN there would be drawn as NaN."""
    lineage = json.dumps({"metrics": {"training_curve": curve}})
    answer = _upload(client, lineage=(None, lineage))
    expected = "lineage.metrics.training_curve" + (f".{field}" if field else "")
    _error(answer, 422, expected)
    nan = '{"metrics": {"training_curve": {"steps": [0], "loss": [NaN]}}}'  # Python's JSON
    _error(_upload(client, lineage=(None, nan)), 422, "lineage.metrics.training_curve.loss[0]")
    good = json.dumps({"metrics": {"training_curve": {"steps": [0, 10], "loss": [0.5, 0.25]}}})
    assert _upload(client, lineage=(None, good)).status_code == 201
