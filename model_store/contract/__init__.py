"""The model store's contract as tests any backend runs: `store.py`'s semantics, checked.

A backend's test module subclasses `StoreContract` and gives it a `store` fixture that yields a
fresh, empty store of that backend (pytest then runs every test below on it):

    import pytest
    from model_store.contract import StoreContract

    class TestMyStore(StoreContract):
        @pytest.fixture
        def store(self, tmp_path):
            with open_my_store(tmp_path) as store:
                yield store

coexist's SQL store runs them on SQLite and PostgreSQL (tests/model_store/contract/). Needs
pytest (the `dev` extra); the float16 / bfloat16 case also torch (skipped without it).

| module        | what                                                                  |
|---------------|-----------------------------------------------------------------------|
| `models`      | create, get, list with filters and pagination, update, delete          |
| `versions`    | numbering, resolve, load, archive / delete policy, events, change token |
| `idempotency` | idempotent registration with a key                                     |
"""

from model_store.contract.idempotency import IdempotencyContract
from model_store.contract.models import ModelsContract
from model_store.contract.versions import VersionsContract


class StoreContract(ModelsContract, VersionsContract, IdempotencyContract):
    """Every contract test; a subclass provides the `store` fixture (module docstring)."""


__all__ = ["IdempotencyContract", "ModelsContract", "StoreContract", "VersionsContract"]
