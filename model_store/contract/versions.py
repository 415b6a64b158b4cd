"""Versions and aliases: numbering, resolve, load, archive/delete policy, events, change token."""

from __future__ import annotations

import hashlib

import pytest

from model_store.errors import Conflict, InvalidArgument, InvalidArtifact, NotFound
from model_store.store import ModelStore
from model_store.testing import qnet_spec, qnet_tensors, qnet_weights, test_lineage

NAME = "particle/task/a3"


SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))


def _register(store: ModelStore, seed: int, **kw):
    return store.register_version(
        NAME, spec=SPEC, weights=qnet_weights(SPEC, seed=seed), lineage=test_lineage(), **kw
    )


class VersionsContract:
    """Versions and aliases: numbering, resolve, load, archive/delete policy, events, change token. (a backend's tests provide the `store` fixture)."""

    @pytest.fixture
    def model(self, store: ModelStore) -> str:
        store.create_model(NAME, env="particle", kind="task", goals=["a3"], obs_dim=8, n_actions=5)
        return NAME

    def test_register_stores_metadata_checksum_and_lineage(
        self, store: ModelStore, model: str
    ) -> None:
        blob = qnet_weights(SPEC, seed=3)
        lineage = test_lineage(config={"lr": 3e-4, "hidden": [16]}, seed=11, metrics={"ret": -1.5})
        mv = store.register_version(model, spec=SPEC, weights=blob, lineage=lineage)
        assert (mv.name, mv.version, mv.status) == (NAME, 1, "ready")
        assert mv.sha256 == hashlib.sha256(blob).hexdigest()
        assert mv.size_bytes == len(blob)
        assert mv.spec == SPEC
        assert mv.ref == "particle/task/a3/1"
        assert store.get_version(model, 1) == mv
        assert store.get_version(model, 1).lineage == lineage
        assert store.load_weights(model, 1) == blob
        assert store.get_model(model).aliases == {"latest": 1}

    def test_float16_and_bfloat16_weights_are_accepted(self, store: ModelStore, model: str) -> None:
        torch = pytest.importorskip("torch")
        import safetensors.torch

        store.register_version(
            model, spec=SPEC, weights=qnet_weights(SPEC, dtype="float16"), lineage=test_lineage()
        )
        bf16 = {k: torch.from_numpy(v).to(torch.bfloat16) for k, v in qnet_tensors(SPEC).items()}
        mv = store.register_version(
            model, spec=SPEC, weights=safetensors.torch.save(bf16), lineage=test_lineage()
        )
        assert mv.version == 2

    def test_versions_are_gapless_and_never_reused(self, store: ModelStore, model: str) -> None:
        assert [_register(store, s).version for s in range(3)] == [1, 2, 3]
        store.set_alias(model, "latest", 2)  # no alias may point at a deleted version
        store.delete_version(model, 3)
        assert _register(store, 9).version == 4
        assert [v.version for v in store.list_versions(model)] == [4, 2, 1]

    def test_resolve_by_alias_number_and_bare_name(self, store: ModelStore, model: str) -> None:
        v1 = _register(store, 1)
        v2 = _register(store, 2, aliases=("latest", "candidate"))
        assert store.resolve(f"{model}@latest") == v2
        assert store.resolve(f"{model}@candidate") == v2
        assert store.resolve(f"{model}/1") == v1
        with pytest.raises(NotFound) as err:  # a bare name means @production, not set yet
            store.resolve(model)
        assert err.value.field == "alias"
        assert "production" in str(err.value) and "candidate, latest" in str(err.value)
        store.set_alias(model, "production", 1)
        assert store.resolve(model) == v1
        with pytest.raises(NotFound) as err:
            store.resolve(f"{model}/7")
        assert err.value.field == "version"
        with pytest.raises(NotFound) as err:
            store.resolve("particle/task/zz@latest")
        assert err.value.field == "name"

    def test_set_alias_moves_it_and_unchanged_set_is_no_event(
        self, store: ModelStore, model: str
    ) -> None:
        _register(store, 1)
        _register(store, 2)
        store.set_alias(model, "production", 1)
        token = store.change_token()
        store.set_alias(model, "production", 1)
        assert store.change_token() == token
        store.set_alias(model, "production", 2)
        assert store.change_token() != token
        assert store.get_model(model).aliases == {"latest": 2, "production": 2}
        store.delete_alias(model, "production")
        assert store.get_model(model).aliases == {"latest": 2}
        with pytest.raises(NotFound):
            store.delete_alias(model, "production")
        with pytest.raises(NotFound):
            store.set_alias(model, "production", 5)
        with pytest.raises(InvalidArgument):
            store.set_alias(model, "Prod!", 1)

    def test_archive_refuses_aliased_versions_and_keeps_data(
        self, store: ModelStore, model: str
    ) -> None:
        v1 = _register(store, 1)
        _register(store, 2)
        store.set_alias(model, "production", 1)
        with pytest.raises(Conflict) as err:
            store.archive_version(model, 1)
        assert "production" in str(err.value)
        assert store.get_version(model, 1).status == "ready"
        store.set_alias(model, "production", 2)
        archived = store.archive_version(model, 1)
        assert archived.status == "archived"
        assert store.archive_version(model, 1) == archived  # idempotent
        assert store.load_weights(model, 1) == qnet_weights(SPEC, seed=1)
        assert store.resolve(f"{model}/1").sha256 == v1.sha256
        assert [v.version for v in store.list_versions(model, include_archived=False)] == [2]
        with pytest.raises(Conflict):
            store.set_alias(model, "rollback", 1)

    def test_delete_version_is_refused_while_an_alias_points_at_it(
        self, store: ModelStore, model: str
    ) -> None:
        """As archiving: deleting what `production` serves would silently stop serving the goal."""
        _register(store, 1)
        _register(store, 2)
        store.set_alias(model, "production", 2)
        since = store.events()[-1].id
        with pytest.raises(Conflict, match="latest, production") as refused:
            store.delete_version(model, 2)
        assert refused.value.field == "version"
        assert store.get_model(model).aliases == {"latest": 2, "production": 2}
        assert store.load_weights(model, 2)  # nothing was deleted
        assert store.events(since) == []
        store.set_alias(model, "latest", 1)
        store.set_alias(model, "production", 1)
        since = store.events()[-1].id
        store.delete_version(model, 2)
        with pytest.raises(NotFound):
            store.load_weights(model, 2)
        assert [(e.kind, e.version) for e in store.events(since)] == [("version_deleted", 2)]

    def test_parents_must_exist(self, store: ModelStore, model: str) -> None:
        _register(store, 1)
        mv = store.register_version(
            model,
            spec=SPEC,
            weights=qnet_weights(SPEC),
            lineage=test_lineage(parents=(f"{NAME}/1",)),
        )
        assert mv.lineage.parents == (f"{NAME}/1",)
        for parents, field in (
            ((f"{NAME}/9",), "lineage.parents[0]"),
            ((f"{NAME}/1", f"{NAME}@latest"), "lineage.parents[1]"),
        ):
            with pytest.raises(InvalidArtifact) as err:
                store.register_version(
                    model,
                    spec=SPEC,
                    weights=qnet_weights(SPEC),
                    lineage=test_lineage(parents=parents),
                )
            assert err.value.field == field

    def test_events_and_change_token_follow_every_write(
        self, store: ModelStore, model: str
    ) -> None:
        t0 = store.change_token()
        _register(store, 1, aliases=("latest", "production"))
        t1 = store.change_token()
        assert t1 != t0
        assert store.change_token() == t1  # reads do not change it
        events = store.events()
        assert [e.id for e in events] == list(range(1, len(events) + 1))
        assert [(e.kind, e.version, e.alias) for e in events] == [
            ("model_created", None, None),
            ("version_registered", 1, None),
            ("alias_set", 1, "latest"),
            ("alias_set", 1, "production"),
        ]
        assert store.events(since_id=2, limit=1)[0].kind == "alias_set"
        assert t1.startswith(f"{events[-1].id}-")
        with pytest.raises(InvalidArgument):
            store.events(limit=0)

    def test_numeric_last_segment_refs_resolve_without_ambiguity(self, store: ModelStore) -> None:
        row = "particle/task/4"  # a row goal of the particle world
        store.create_model(row, env="particle", kind="task", goals=["4"], obs_dim=8, n_actions=5)
        mv = store.register_version(
            row,
            spec=SPEC,
            weights=qnet_weights(SPEC),
            lineage=test_lineage(),
            aliases=("latest", "production"),
        )
        assert store.resolve(row) == mv  # the model at production, not version 4 of particle/task
        assert store.resolve(f"{row}/1") == mv
        assert store.resolve(f"{row}@latest") == mv
        for nested in ("particle/task", "particle/task/4/x"):
            with pytest.raises(Conflict) as err:
                store.create_model(
                    nested, env="particle", kind="task", goals=["4"], obs_dim=8, n_actions=5
                )
            assert err.value.field == "name" and "ambiguous" in str(err.value)
