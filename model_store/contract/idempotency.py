"""Idempotent registration: a retry with the same key answers the version the key registered
(no second version, no event, aliases untouched); the key with other weights or another spec is a
`Conflict`; keys are per model; a bad key is `InvalidArgument`."""

from __future__ import annotations

import pytest

from model_store.errors import Conflict, InvalidArgument
from model_store.store import ModelStore
from model_store.testing import qnet_spec, qnet_weights, test_lineage

NAME, OTHER = "particle/task/a2", "particle/task/b3"


SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(4,))


KEY = "0f6c2e9a-upload-1"


def _register(
    store: ModelStore, name: str = NAME, *, seed: int = 0, idempotency_key: str | None = None
) -> int:
    version = store.register_version(
        name,
        spec=SPEC,
        weights=qnet_weights(SPEC, seed=seed),
        lineage=test_lineage(),
        idempotency_key=idempotency_key,
    )
    return version.version


class IdempotencyContract:
    """Idempotent registration: a retry with the same key answers the version the key registered (a backend's tests provide the `store` fixture)."""

    @pytest.fixture
    def models(self, store: ModelStore) -> ModelStore:
        for name in (NAME, OTHER):
            goal = name.rsplit("/", 1)[1]
            store.create_model(
                name, env="particle", kind="task", goals=(goal,), obs_dim=8, n_actions=5
            )
        return store

    def test_a_retry_answers_the_version_its_key_registered(self, models: ModelStore) -> None:
        first = _register(models, idempotency_key=KEY)
        events = models.events()
        models.set_alias(NAME, "latest", first)
        _register(models, seed=5)  # version 2 moves `latest`
        again = _register(models, idempotency_key=KEY)
        assert again == first == 1
        assert [v.version for v in models.list_versions(NAME)] == [2, 1]
        assert models.resolve(f"{NAME}@latest").version == 2  # the retry moved no alias
        assert len(models.events()) == len(events) + 2  # version 2 and its alias move, nothing else

    def test_a_key_names_one_upload(self, models: ModelStore) -> None:
        _register(models, idempotency_key=KEY)
        with pytest.raises(Conflict) as caught:
            _register(models, seed=1, idempotency_key=KEY)
        assert caught.value.field == "idempotency_key" and "version 1" in caught.value.message
        assert _register(models, OTHER, idempotency_key=KEY) == 1  # keys are per model
        assert _register(models, seed=1) == 2  # no key: a new version, as before

    @pytest.mark.parametrize("key", ["", "has space", "k" * 129, "ünïcode"])
    def test_a_bad_key_is_invalid(self, models: ModelStore, key: str) -> None:
        with pytest.raises(InvalidArgument) as caught:
            _register(models, idempotency_key=key)
        assert caught.value.field == "idempotency_key"
        assert models.list_versions(NAME) == []
