"""Registered models: create, get, list with filters and pagination, update, delete."""

from __future__ import annotations

from typing import Any

import pytest

from model_store.errors import AlreadyExists, InvalidArgument, NotFound
from model_store.store import ModelStore


def _create(store: ModelStore, name: str, **kw) -> None:
    env, kind, goal = name.split("/")
    args: dict[str, Any] = {
        "env": env,
        "kind": kind,
        "goals": goal.split("+"),
        "obs_dim": 8,
        "n_actions": 5,
    }
    args.update(kw)
    store.create_model(name, **args)


class ModelsContract:
    """Registered models: create, get, list with filters and pagination, update, delete. (a backend's tests provide the `store` fixture)."""

    def test_create_and_get_round_trip(self, store: ModelStore) -> None:
        made = store.create_model(
            "particle/joint/a2+b3",
            env="particle",
            kind="joint",
            goals=["a2", "b3"],
            obs_dim=12,
            n_actions=5,
            description="joint baseline",
            tags={"team": "rl", "stage": "dev"},
        )
        got = store.get_model("particle/joint/a2+b3")
        assert got == made
        assert got.goals == ("a2", "b3")
        assert got.tags == {"stage": "dev", "team": "rl"}
        assert got.aliases == {}
        assert got.created_at.tzinfo is not None

    def test_duplicate_name_is_already_exists_unless_identical_and_exist_ok(
        self,
        store: ModelStore,
    ) -> None:
        _create(store, "particle/task/a3")
        with pytest.raises(AlreadyExists) as err:
            _create(store, "particle/task/a3")
        assert err.value.field == "name"
        again = store.create_model(
            "particle/task/a3",
            env="particle",
            kind="task",
            goals=["a3"],
            obs_dim=8,
            n_actions=5,
            exist_ok=True,
        )
        assert again.name == "particle/task/a3"
        with pytest.raises(AlreadyExists):  # exist_ok, but the sizes differ
            _create(store, "particle/task/a3", obs_dim=9, exist_ok=True)

    @pytest.mark.parametrize(
        ("overrides", "field"),
        [
            ({"kind": "policy"}, "kind"),
            ({"env": "Particle World"}, "env"),
            ({"goals": []}, "goals"),
            ({"goals": ["a 3"]}, "goals[0]"),
            ({"obs_dim": 0}, "obs_dim"),
            ({"n_actions": True}, "n_actions"),
            ({"tags": {"bad key": "x"}}, "tags.bad key"),
        ],
    )
    def test_create_rejects_bad_fields_naming_them(
        self, store: ModelStore, overrides: dict, field: str
    ) -> None:
        with pytest.raises(InvalidArgument) as err:
            _create(store, "particle/task/a3", **overrides)
        assert err.value.field == field
        assert field.split(".")[0].split("[")[0] in str(err.value)
        assert store.list_models().items == ()

    def test_list_filters_by_env_kind_goal_and_tag(self, store: ModelStore) -> None:
        _create(store, "particle/task/a3", tags={"team": "x"})
        _create(store, "particle/impact/a3")
        _create(store, "particle/joint/a2+b3", tags={"team": "y"})
        _create(store, "grid/task/a3", tags={"team": "x", "old": ""})

        def names(**kw) -> list[str]:
            return [m.name for m in store.list_models(**kw).items]

        assert names() == [
            "grid/task/a3",
            "particle/impact/a3",
            "particle/joint/a2+b3",
            "particle/task/a3",
        ]
        assert names(env="grid") == ["grid/task/a3"]
        assert names(kind="task") == ["grid/task/a3", "particle/task/a3"]
        assert names(goal="b3") == ["particle/joint/a2+b3"]
        assert names(goal="a3", env="particle") == ["particle/impact/a3", "particle/task/a3"]
        assert names(tag="team") == ["grid/task/a3", "particle/joint/a2+b3", "particle/task/a3"]
        assert names(tag="team=x") == ["grid/task/a3", "particle/task/a3"]
        assert names(tag="old=") == ["grid/task/a3"]
        assert names(tag="missing") == []

    def test_pagination_visits_every_model_once(self, store: ModelStore) -> None:
        expected = [f"particle/task/g{i:02d}" for i in range(7)]
        for name in reversed(expected):
            _create(store, name)
        seen: list[str] = []
        token = None
        pages = 0
        while True:
            page = store.list_models(page_size=3, page_token=token)
            seen += [m.name for m in page.items]
            pages += 1
            token = page.next_page_token
            if token is None:
                break
        assert seen == expected
        assert pages == 3
        with pytest.raises(InvalidArgument) as err:
            store.list_models(page_token="not-a-token")
        assert err.value.field == "page_token"
        with pytest.raises(InvalidArgument):
            store.list_models(page_size=0)

    def test_update_replaces_tags_and_description(self, store: ModelStore) -> None:
        _create(store, "particle/task/a3", tags={"a": "1", "b": "2"})
        before = store.get_model("particle/task/a3")
        updated = store.update_model(
            "particle/task/a3", description="new", tags={"a": "9", "c": "3"}
        )
        assert updated.description == "new"
        assert updated.tags == {"a": "9", "c": "3"}
        assert updated.updated_at >= before.updated_at
        kept = store.update_model("particle/task/a3", description="newer")
        assert kept.tags == {"a": "9", "c": "3"} == store.get_model("particle/task/a3").tags

    def test_delete_model_and_unknown_model_errors(self, store: ModelStore) -> None:
        _create(store, "particle/task/a3")
        store.delete_model("particle/task/a3")
        for call in (
            lambda: store.get_model("particle/task/a3"),
            lambda: store.delete_model("particle/task/a3"),
            lambda: store.update_model("particle/task/a3", description="x"),
            lambda: store.list_versions("particle/task/a3"),
        ):
            with pytest.raises(NotFound) as err:
                call()
            assert "particle/task/a3" in str(err.value)
            assert err.value.field == "name"
        kinds = [e.kind for e in store.events()]
        assert kinds == ["model_created", "model_deleted"]
