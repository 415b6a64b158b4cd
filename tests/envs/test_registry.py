"""envs.registry: environments come from `coexist.envs` entry points (coexist's own too) or from
`register_env`; a plugin that fails to load is named, never silently missing, and does not take
the others down."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest

from envs import registry
from envs.registry import (
    EnvPlugin,
    PlainDrawing,
    env_plugin,
    get_domain,
    get_drawing,
    known_envs,
    make_env,
    register_env,
)


def test_coexists_own_worlds_come_from_its_entry_points() -> None:
    points = {p.name: p for p in registry.entry_points(group=registry.ENTRY_POINT_GROUP)}
    assert {"particle", "cooking"} <= set(points)
    for name in ("particle", "cooking"):
        assert env_plugin(name) is points[name].load()
        assert get_domain(name).name == name
    assert {"particle", "cooking"} <= set(known_envs())


def test_register_env_adds_replaces_and_refuses(tinyline: str) -> None:
    plugin = env_plugin(tinyline)
    assert tinyline in known_envs() and get_domain(tinyline) is plugin.domain
    env = make_env(tinyline, ("c0", "c4"))
    assert env.possible_agents == ["agent_0", "agent_1"]
    register_env(plugin)  # the same registration again: nothing changes
    other = EnvPlugin(domain=plugin.domain, make_env=plugin.make_env)
    with pytest.raises(ValueError, match="already registered"):
        register_env(other)
    register_env(other, replace=True)
    assert env_plugin(tinyline) is other
    assert isinstance(get_drawing(tinyline), PlainDrawing)  # no drawing: the plain one
    with pytest.raises(ValueError, match=r"expected an envs\.registry\.EnvPlugin"):
        register_env(plugin.domain)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"does not implement envs\.base\.Domain"):
        register_env(EnvPlugin(domain=object(), make_env=plugin.make_env))  # type: ignore[arg-type]


def test_an_unknown_env_is_named_with_the_known_ones() -> None:
    with pytest.raises(ValueError, match=r"unknown environment 'nowhere' \(known: .*particle"):
        get_domain("nowhere")


@pytest.fixture
def fresh_registry(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The registry as a new process finds it, over the given entry points only."""
    monkeypatch.setattr(registry, "_registry", {})
    monkeypatch.setattr(registry, "_broken", {})
    monkeypatch.setattr(registry, "_loaded", False)
    yield


def _points(*specs: tuple[str, str]) -> list[EntryPoint]:
    return [EntryPoint(name, value, registry.ENTRY_POINT_GROUP) for name, value in specs]


def test_a_broken_plugin_is_named_and_the_others_load(
    fresh_registry: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    points = _points(
        ("particle", "envs.particle.plugin:ENV"),
        ("ghost", "no_such_package.plugin:ENV"),
        ("misnamed", "envs.cooking.plugin:ENV"),
        ("notaplugin", "envs.particle.domain:PARTICLE"),
    )
    monkeypatch.setattr(registry, "entry_points", lambda group: points)
    assert known_envs() == ("particle",)
    with pytest.raises(ValueError, match=r"plugin 'ghost' failed to load .*no_such_package"):
        get_domain("ghost")
    with pytest.raises(ValueError, match="its domain is named 'cooking'; name the entry point"):
        get_domain("misnamed")
    with pytest.raises(ValueError, match=r"expected an envs\.registry\.EnvPlugin"):
        get_domain("notaplugin")


def test_no_entry_points_at_all_says_to_reinstall(
    fresh_registry: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(registry, "entry_points", lambda group: [])
    with pytest.raises(ValueError, match="reinstall coexist"):
        get_domain("particle")


def test_the_plain_drawing_draws_any_env(tinyline: str) -> None:
    env = make_env(tinyline, ("c0", "c4"))
    env.reset(seed=0)
    drawing = PlainDrawing()
    scene, frame = drawing.scene(env).to_json(), drawing.scene_frame(env).to_json()
    assert scene["width"] == 2.0 and len(scene["agent_colours"]) == 2
    assert [a["index"] for a in frame["agents"]] == [0, 1]


def test_a_plugin_that_registers_itself_on_import_loads(
    fresh_registry: None, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Its import calls `register_env` while the entry points are loading: no deadlock, and the
    entry point's object is the registration."""
    (tmp_path / "self_registering.py").write_text(
        "from envs.particle.plugin import ENV as PARTICLE_ENV\n"
        "from envs.registry import register_env\n"
        "ENV = PARTICLE_ENV\n"
        "register_env(ENV)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    points = _points(("particle", "self_registering:ENV"))
    monkeypatch.setattr(registry, "entry_points", lambda group: points)
    assert known_envs() == ("particle",)
    assert env_plugin("particle") is sys.modules["self_registering"].ENV
