"""The plugin's own tests, run as a plugin author runs them (with the distribution installed):
coexist's conformance check on the environment, coexist's store contract on the backend, and
what the backend adds: one folder is one store for every opening, a reader makes none."""

from __future__ import annotations

import fcntl
from collections.abc import Iterator
from pathlib import Path

import pytest
from tinyline.store import TinylineStore

from envs.check import assert_env_conforms
from model_store.contract import StoreContract
from model_store.defaults import open_store
from model_store.errors import InvalidArgument
from model_store.store import ModelStore


def test_the_corridor_conforms() -> None:
    assert_env_conforms("tinyline")  # found by its entry point


class TestTinylineStore(StoreContract):
    @pytest.fixture
    def store(self, tmp_path: Path) -> Iterator[ModelStore]:
        with open_store(f"tinyline://{tmp_path}/models", create=True) as store:
            assert isinstance(store, TinylineStore)  # picked by the scheme
            yield store


def test_every_opening_of_a_folder_is_one_store(tmp_path: Path) -> None:
    url = f"tinyline://{tmp_path}/models"
    with open_store(url, create=True) as writer, open_store(url) as reader:
        writer.create_model("tinyline/task/c1", env="tinyline", kind="task", goals=["c1"],
                            obs_dim=4, n_actions=3)  # fmt: skip
        assert reader.get_model("tinyline/task/c1") == writer.get_model("tinyline/task/c1")
        assert reader.change_token() == writer.change_token()
        lock = writer.lock("a batch")
        assert lock is not None  # the backend offers coexist's Ray backend a lock
        with lock:  # a file's lock: a second holder must wait for it
            (held,) = (tmp_path / "models" / "locks").iterdir()
            with open(held, "a+b") as other, pytest.raises(BlockingIOError):
                fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)


def test_a_reader_makes_no_store(tmp_path: Path) -> None:
    with pytest.raises(InvalidArgument) as refused:
        open_store(f"tinyline://{tmp_path}/none")
    assert refused.value.field == "store_url" and not (tmp_path / "none").exists()
