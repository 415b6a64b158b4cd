"""Bad uploads, tampered bytes, newer schemas and vanished databases: the right error, and the
registry's state is unchanged (no version, no alias move, no event)."""

# ruff: noqa: F811  (the fixtures imported from store_fixtures are re-bound as test arguments)

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np
import psycopg
import pytest
import safetensors.numpy
from sqlalchemy import create_engine, text
from store_fixtures import pg_url, store, store_url  # noqa: F401

from model_store.errors import (
    ArtifactTooLarge,
    ChecksumMismatch,
    InvalidArtifact,
    NotFound,
    SchemaTooNew,
    StoreUnavailable,
)
from model_store.sql import SqlModelStore
from model_store.sql.engine import normalise_url
from model_store.testing import qnet_spec, qnet_tensors, qnet_weights, test_lineage

NAME = "particle/task/a3"
SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
GOOD = qnet_weights(SPEC)


def _with(tensor: str, value: np.ndarray) -> bytes:
    tensors = qnet_tensors(SPEC)
    tensors[tensor] = value
    return safetensors.numpy.save(tensors)


def _nan_bias() -> bytes:
    bias = qnet_tensors(SPEC)["layers.1.bias"].copy()
    bias[2] = np.nan
    return _with("layers.1.bias", bias)


BAD_UPLOADS: dict[str, tuple[Any, bytes, str, str]] = {
    "truncated": (SPEC, GOOD[: len(GOOD) // 2], "weights", "safetensors"),
    "corrupt header": (SPEC, b"\xff" * 8 + GOOD[8:], "weights", "safetensors"),
    "not safetensors": (SPEC, b"PK\x03\x04 a zip, not weights", "weights", "safetensors"),
    "empty": (SPEC, b"", "weights", "safetensors"),
    "wrong shape": (
        SPEC,
        _with("layers.0.weight", np.zeros((16, 9), np.float32)),
        "weights",
        "layers.0.weight",
    ),
    "missing tensor": (
        SPEC,
        safetensors.numpy.save({"layers.0.weight": np.zeros((16, 8), np.float32)}),
        "weights",
        "layers.0.bias",
    ),
    "nan": (SPEC, _nan_bias(), "weights", "layers.1.bias"),
    "inf": (
        SPEC,
        _with("layers.0.bias", np.full(16, np.inf, np.float32)),
        "weights",
        "layers.0.bias",
    ),
    "float64": (SPEC, _with("layers.0.bias", np.zeros(16, np.float64)), "weights", "dtype"),
    "int32": (SPEC, _with("layers.0.bias", np.zeros(16, np.int32)), "weights", "dtype"),
    "spec obs_dim": (qnet_spec(obs_dim=9, hidden=(16,)), GOOD, "spec.obs_dim", "obs_dim=8"),
    "spec n_actions": (qnet_spec(n_actions=4, hidden=(16,)), GOOD, "spec.n_actions", "n_actions"),
    "spec vs weights": (qnet_spec(hidden=(32,)), GOOD, "weights", "layers.0.weight"),
    "spec format": ({**SPEC, "format": "onnx"}, GOOD, "spec", "format"),
    "spec missing field": (
        {k: v for k, v in SPEC.items() if k != "hidden"},
        GOOD,
        "spec",
        "hidden",
    ),
    "spec not a dict": (["not", "a", "spec"], GOOD, "spec", "spec"),
}


def _make_model(store: SqlModelStore) -> str:
    store.create_model(NAME, env="particle", kind="task", goals=["a3"], obs_dim=8, n_actions=5)
    store.register_version(
        NAME, spec=SPEC, weights=GOOD, lineage=test_lineage(), aliases=("latest", "production")
    )
    return NAME


@pytest.fixture
def model(store: SqlModelStore) -> str:
    return _make_model(store)


def _state(store: SqlModelStore) -> tuple:
    model = store.get_model(NAME)
    return (store.change_token(), store.list_versions(NAME), model.aliases, store.events())


def _assert_rejected_without_trace(store: SqlModelStore, case: str) -> None:
    spec, weights, field, mentions = BAD_UPLOADS[case]
    before = _state(store)
    with pytest.raises(InvalidArtifact) as err:
        store.register_version(
            NAME, spec=spec, weights=weights, lineage=test_lineage(), aliases=("latest", "x")
        )
    assert err.value.field == field, case
    assert mentions in str(err.value), case
    assert _state(store) == before, case


@pytest.mark.parametrize("case", list(BAD_UPLOADS))
def test_bad_upload_is_rejected_and_leaves_no_trace(tmp_path: Path, case: str) -> None:
    """Validation is the same code for every backend: the whole matrix runs on SQLite."""
    with SqlModelStore(f"sqlite:///{tmp_path / 'm.db'}") as store:
        _make_model(store)
        _assert_rejected_without_trace(store, case)
        mv = store.register_version(NAME, spec=SPEC, weights=GOOD, lineage=test_lineage())
        assert mv.version == 2


def test_bad_uploads_leave_no_trace_on_every_backend(store: SqlModelStore, model: str) -> None:
    for case in ("truncated", "nan", "spec vs weights", "float64"):
        _assert_rejected_without_trace(store, case)


def test_size_limit_and_bad_lineage(store_url: str) -> None:
    with SqlModelStore(store_url, max_artifact_bytes=len(GOOD) - 1) as store:
        store.create_model(NAME, env="particle", kind="task", goals=["a3"], obs_dim=8, n_actions=5)
        with pytest.raises(ArtifactTooLarge) as too_large:
            store.register_version(NAME, spec=SPEC, weights=GOOD, lineage=test_lineage())
        assert too_large.value.field == "weights" and str(len(GOOD) - 1) in str(too_large.value)
        with pytest.raises(InvalidArtifact) as err:
            store.register_version(
                NAME,
                spec=SPEC,
                weights=GOOD,
                lineage=test_lineage(metrics={"return": float("nan")}),
            )
        assert err.value.field == "lineage.metrics"
        with pytest.raises(NotFound):
            store.register_version(
                "particle/task/zz", spec=SPEC, weights=GOOD, lineage=test_lineage()
            )
        assert store.list_versions(NAME) == []


def test_tampered_weights_fail_the_checksum(store_url: str, store: SqlModelStore, model: str):
    engine = create_engine(normalise_url(store_url))
    tampered = bytearray(GOOD)
    tampered[-1] ^= 0x01
    with engine.begin() as conn:
        conn.execute(text("UPDATE model_versions SET weights = :w"), {"w": bytes(tampered)})
    engine.dispose()
    with pytest.raises(ChecksumMismatch) as err:
        store.load_weights(model, 1)
    assert "sha256" in str(err.value)
    assert store.get_version(model, 1).sha256  # metadata still readable


def test_schema_newer_than_code_is_refused(store_url: str, store: SqlModelStore) -> None:
    engine = create_engine(normalise_url(store_url))
    with engine.begin() as conn:
        conn.execute(text("UPDATE alembic_version SET version_num = '9999_from_the_future'"))
    engine.dispose()
    with pytest.raises(SchemaTooNew) as err:
        SqlModelStore(store_url)
    assert "9999_from_the_future" in str(err.value) and "upgrade coexist" in str(err.value)


def test_empty_database_without_auto_migrate_is_an_error(store_url: str) -> None:
    with pytest.raises(Exception, match="older than this coexist"):
        SqlModelStore(store_url, auto_migrate=False)


def test_sqlite_directory_removed_mid_use(tmp_path: Path) -> None:
    folder = tmp_path / "data"
    store = SqlModelStore(f"sqlite:///{folder / 'models.db'}")
    store.create_model(NAME, env="particle", kind="task", goals=["a3"], obs_dim=8, n_actions=5)
    shutil.rmtree(folder)
    for call in (
        lambda: store.get_model(NAME),
        store.change_token,
        lambda: store.register_version(NAME, spec=SPEC, weights=GOOD, lineage=test_lineage()),
    ):
        with pytest.raises(StoreUnavailable) as err:
            call()
        assert "unavailable" in str(err.value) and "models.db" in str(err.value)
    assert not folder.exists()  # nothing was silently re-created
    store.close()


@pytest.mark.postgres
def test_postgres_closed_port_and_dropped_schema(pg_url: str) -> None:
    with pytest.raises(StoreUnavailable) as err:
        SqlModelStore("postgresql://postgres@127.0.0.1:1/test")
    assert "127.0.0.1:1" in str(err.value)
    store = SqlModelStore(pg_url)
    store.create_model(NAME, env="particle", kind="task", goals=["a3"], obs_dim=8, n_actions=5)
    schema = pg_url.rsplit("search_path%3D", 1)[1]
    with psycopg.connect(pg_url.split("?")[0], autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA "{schema}" CASCADE')
    with pytest.raises(StoreUnavailable):
        store.get_model(NAME)
    store.close()


def test_nul_characters_get_the_same_answer_on_both_backends(store: SqlModelStore) -> None:
    """PostgreSQL's text type cannot hold NUL (it raised, a 503): a name or job id with one
    names nothing (NotFound), a filter, description or tag value with one is refused naming its
    field, a page token whose name holds one is not ours; SQLite answers the same."""
    import base64
    import json

    from model_store.errors import InvalidArgument
    from trainer.jobs.table import JobTable

    store.create_model(NAME, env="particle", kind="task", goals=["a3"], obs_dim=8, n_actions=5)
    raw = json.dumps({"after": "a\x00"}).encode()
    token = base64.urlsafe_b64encode(raw).decode().rstrip("=")
    refused = {
        "env": lambda: store.list_models(env="particle\x00"),
        "goal": lambda: store.list_models(goal="a3\x00"),
        "tag": lambda: store.list_models(tag="k=v\x00"),
        "page_token": lambda: store.list_models(page_token=token),
        "description": lambda: store.update_model(NAME, description="x\x00y"),
        "tags.k": lambda: store.update_model(NAME, tags={"k": "v\x00"}),
    }
    for field, call in refused.items():
        with pytest.raises(InvalidArgument) as err:
            call()
        assert err.value.field == field
    with pytest.raises(InvalidArgument, match="description"):
        store.create_model(
            "particle/task/a4",
            env="particle",
            kind="task",
            goals=["a4"],
            obs_dim=8,
            n_actions=5,
            description="\x00",
        )
    for call in (
        lambda: store.get_model(NAME + "\x00"),
        lambda: store.list_versions(NAME + "\x00"),
        lambda: store.delete_model(NAME + "\x00"),
        lambda: store.load_weights(NAME + "\x00", 1),
    ):
        with pytest.raises(NotFound):
            call()
    jobs = JobTable(store.url.render_as_string(hide_password=False))
    for job_call in (jobs.get, jobs.status, jobs.cancel):
        with pytest.raises(NotFound):
            job_call("job\x00")
    assert [m.name for m in store.list_models().items] == [NAME]  # nothing else was written
    assert store.get_model(NAME).description == ""
