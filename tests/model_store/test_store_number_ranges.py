"""Numbers at and past the store's column types, on SQLite and PostgreSQL alike: a version
number is 1..2^31-1 (`MAX_VERSION`, the Integer columns), an event id 0..2^63-1 (BigInteger), a
model's sizes 1..2^31-1. Out of range is `InvalidArgument` (422) before any SQL runs; in range
but absent is `NotFound` (404); never an overflow from the driver or "integer out of range" from
PostgreSQL (which the store would report as `StoreUnavailable`, 503)."""

# ruff: noqa: F811  (the fixtures imported from store_fixtures are re-bound as test arguments)

from __future__ import annotations

import pytest
from store_fixtures import pg_url, store, store_url  # noqa: F401

from model_store.errors import InvalidArgument, NotFound
from model_store.naming import MAX_VERSION
from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_weights, test_lineage

NAME = "particle/task/a2"
SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(4,))
PAST_64_BITS = 2**63
PAST_POSTGRES = 2**31


@pytest.fixture
def one_version(store: SqlModelStore) -> SqlModelStore:
    store.create_model(NAME, env="particle", kind="task", goals=("a2",), obs_dim=8, n_actions=5)
    store.register_version(NAME, spec=SPEC, weights=qnet_weights(SPEC), lineage=test_lineage())
    return store


def test_the_documented_range_is_the_columns() -> None:
    assert MAX_VERSION == PAST_POSTGRES - 1


@pytest.mark.parametrize("version", [PAST_POSTGRES, PAST_64_BITS, 10**30])
def test_versions_past_the_range_are_invalid(one_version: SqlModelStore, version: int) -> None:
    store = one_version
    for call in (
        lambda: store.resolve(f"{NAME}/{version}"),
        lambda: store.get_version(NAME, version),
        lambda: store.load_weights(NAME, version),
        lambda: store.set_alias(NAME, "production", version),
        lambda: store.archive_version(NAME, version),
        lambda: store.delete_version(NAME, version),
    ):
        with pytest.raises(InvalidArgument) as caught:
            call()
        assert caught.value.field in ("version", "ref")
    assert store.resolve(f"{NAME}@latest").version == 1  # nothing changed


def test_the_largest_version_is_not_found(one_version: SqlModelStore) -> None:
    with pytest.raises(NotFound):
        one_version.resolve(f"{NAME}/{MAX_VERSION}")
    with pytest.raises(NotFound):
        one_version.get_version(NAME, MAX_VERSION)


def test_event_ids_past_64_bits_are_invalid(one_version: SqlModelStore) -> None:
    assert one_version.events(since_id=2**63 - 1) == []
    with pytest.raises(InvalidArgument) as caught:
        one_version.events(since_id=PAST_64_BITS)
    assert caught.value.field == "since_id"


@pytest.mark.parametrize("field", ["obs_dim", "n_actions"])
def test_model_sizes_past_the_column_are_invalid(store: SqlModelStore, field: str) -> None:
    obs_dim, n_actions = (PAST_POSTGRES, 5) if field == "obs_dim" else (8, PAST_POSTGRES)
    with pytest.raises(InvalidArgument) as caught:
        store.create_model(
            NAME, env="particle", kind="task", goals=("a2",), obs_dim=obs_dim, n_actions=n_actions
        )
    assert caught.value.field == field
    assert not store.list_models().items
