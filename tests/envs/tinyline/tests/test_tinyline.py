"""The plugin's own tests, run as a plugin author runs them (with the distribution installed):
coexist's conformance check on the environment, coexist's store contract on the backend."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from tinyline.store import TinylineStore

from envs.check import assert_env_conforms
from model_store.contract import StoreContract
from model_store.defaults import open_store
from model_store.store import ModelStore


def test_the_corridor_conforms() -> None:
    assert_env_conforms("tinyline")  # found by its entry point


class TestTinylineStore(StoreContract):
    @pytest.fixture
    def store(self, tmp_path: Path) -> Iterator[ModelStore]:
        with open_store(f"tinyline://{tmp_path}/models.db", create=True) as store:
            assert isinstance(store, TinylineStore)  # picked by the scheme
            yield store
