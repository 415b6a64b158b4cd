"""Environments by name, and how a package adds its own: the public extension point.

An environment is one `EnvPlugin` (its `Domain`, a PettingZoo factory, how to train it and,
optionally, how to draw it and how global states become observations). It reaches coexist in
one of two ways, like Gymnasium's `register` and its entry points:

- an entry point in the group `coexist.envs` of any installed distribution, naming the
  `EnvPlugin` (or a function returning one); every process (the server, the CLI, a training
  job's subprocess, a Ray worker, the evaluation) loads the group once, on its first look-up:

      [project.entry-points."coexist.envs"]
      tinyline = "tinyline.plugin:ENV"

- `register_env(plugin)` from code, for this process only (a notebook, a test).

coexist's own worlds register through the same entry points (`particle`, `cooking`: this
project's `pyproject.toml`). `docs/extending.md` walks through a new one; `envs.check` is the
conformance check a plugin's own tests run (`coexist env check NAME`).

| function                     | what                                                       |
|------------------------------|------------------------------------------------------------|
| `register_env(plugin)`       | add an environment in this process                         |
| `known_envs()`               | the names of every registered environment                  |
| `env_plugin(name)`           | the whole registration (`ValueError` naming the known ones) |
| `get_domain(name)`           | its `Domain`                                               |
| `make_env(name, goals)`      | a fresh PettingZoo env with one agent per goal             |
| `episode_resets(...)`        | paired start states for comparing methods                  |
| `get_drawing(name)`          | how the console draws it (`PlainDrawing` when it says nothing) |
"""

from __future__ import annotations

import importlib
import logging
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Any, Protocol, runtime_checkable

import numpy as np
from pettingzoo import ParallelEnv

from envs.base import Domain
from envs.scene import AgentMark, Scene, SceneFrame, text

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "coexist.envs"


@runtime_checkable
class Drawing(Protocol):
    """How the web console draws an env of this environment (shapes in its own units,
    `envs.scene`)."""

    def scene(self, env: Any) -> Scene:
        """What does not move in `env` (an env from `make_env`): painted once per episode."""
        ...

    def scene_frame(self, env: Any) -> SceneFrame:
        """Where `env`'s agents and objects are now, in the units of `scene(env)`."""
        ...


class PlainDrawing:
    """The drawing of an environment that gives none: one labelled disc per agent in a row, its
    goal written beside it (positions say nothing about the world; the console's charts of
    rewards and policies carry the episode)."""

    def scene(self, env: Any) -> Scene:
        agents = list(getattr(env, "possible_agents", ()))
        n = max(len(agents), 1)
        return Scene(
            width=float(n),
            height=1.0,
            y_up=True,
            agent_radius=0.2,
            agent_colours=tuple(_PLAIN_COLOURS[i % len(_PLAIN_COLOURS)] for i in range(n)),
            shapes=tuple(
                text(i + 0.5, 0.15, str(name), 0.12, label=f"agent {i}: {name}")
                for i, name in enumerate(agents)
            ),
        )

    def scene_frame(self, env: Any) -> SceneFrame:
        live = set(getattr(env, "agents", ()))
        marks = tuple(
            AgentMark(i, i + 0.5, 0.5, f"agent {i} ({name})", "" if name in live else "done")
            for i, name in enumerate(getattr(env, "possible_agents", ()))
        )
        return SceneFrame(marks)


_PLAIN_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd")


@dataclass(frozen=True)
class StateAdapter:
    """How a global state of an environment (one row per agent) becomes every agent's
    observation, for clients that send states instead of observations (`POST /v1/act`'s
    `states`)."""

    features: tuple[str, ...]
    """One agent's row of the state, e.g. ("x", "y", "vx", "vy")."""
    observations: Callable[[np.ndarray], np.ndarray]
    """(B, N, S) global states -> (B, N, D) every agent's observation."""


StartStates = Callable[[int, int, int], Any]
"""(seed, episodes, n_agents) -> each episode's start state, for `reset(options={"state"})`."""


@dataclass(frozen=True)
class EnvPlugin:
    """One environment's registration.

    `training` says how its networks are trained, read only by the trainer (so the server
    never imports torch): None for the trainer's generic machinery with its default numbers, or
    a `"module:attribute"` reference (or the object itself) to either a
    `trainer.generic.GenericTraining` (the generic machinery, this env's numbers: steps,
    learning rates, gates) or a whole `trainer.domain.EnvTrainer` of its own."""

    domain: Domain
    make_env: Callable[..., ParallelEnv]
    """`make_env(goals=[...], **kwargs)` -> a PettingZoo `ParallelEnv` with one agent per goal
    (a ValueError for goals it cannot host together); coexist passes `max_steps=` (the episode
    length; the env truncates there), and `render_mode="rgb_array"` only where frames are
    recorded (`coexist run --gif`)."""
    training: str | object | None = None
    drawing: Drawing | None = None
    """How the console draws it; None: `PlainDrawing`."""
    start_states: StartStates | None = None
    """Paired starts for comparing methods; None: the env's own start, reseeded per episode."""
    state_adapter: StateAdapter | None = None
    """None: clients send observations only."""

    @property
    def name(self) -> str:
        return self.domain.name


_lock = threading.RLock()
_registry: dict[str, EnvPlugin] = {}
_broken: dict[str, str] = {}  # entry-point name -> why it did not load
_loaded = False
_loading = False  # the entry points are being loaded (a plugin may register itself meanwhile)


def register_env(plugin: EnvPlugin, *, replace: bool = False) -> None:
    """Register `plugin` under its domain's name in this process. ValueError if the name is
    taken by another registration (unless `replace`) or the plugin is not an `EnvPlugin`."""
    _check_plugin(plugin, "register_env")
    _load_entry_points()
    with _lock:
        current = _registry.get(plugin.name)
        if current is not None and current is not plugin and not replace:
            raise ValueError(
                f"env: {plugin.name!r} is already registered (pass replace=True to replace it)"
            )
        _registry[plugin.name] = plugin
        _broken.pop(plugin.name, None)


def unregister_env(name: str) -> None:
    """Forget environment `name` in this process (tests)."""
    _load_entry_points()
    with _lock:
        _registry.pop(name, None)


def _check_plugin(plugin: object, source: str) -> EnvPlugin:
    if not isinstance(plugin, EnvPlugin):
        raise ValueError(f"{source}: expected an envs.registry.EnvPlugin, got {type(plugin)!r}")
    if not isinstance(plugin.domain, Domain):
        raise ValueError(
            f"{source}: domain {type(plugin.domain)!r} does not implement envs.base.Domain"
        )
    if not callable(plugin.make_env):
        raise ValueError(f"{source}: make_env is not callable")
    return plugin


def _load_entry_points() -> None:
    """Every `coexist.envs` entry point, once per process. One that fails to load is logged and
    remembered: asking for it names the failure; the others load."""
    global _loaded, _loading
    if _loaded:
        return
    with _lock:
        if _loaded or _loading:  # _loading: a plugin's import calling `register_env`
            return
        _loading = True
        try:
            _load_each_entry_point()
        finally:
            _loading = False
        _loaded = True


def _load_each_entry_point() -> None:
    """Load every entry point not registered yet; one that fails is remembered."""
    for point in entry_points(group=ENTRY_POINT_GROUP):
        if point.name in _registry:
            continue  # registered from code first, or a second distribution's copy
        try:
            loaded = point.load()
            plugin = _check_plugin(
                loaded() if callable(loaded) and not isinstance(loaded, EnvPlugin) else loaded,
                f"entry point {point.name} = {point.value}",
            )
            if plugin.name != point.name:
                raise ValueError(
                    f"entry point {point.name} = {point.value}: its domain is named "
                    f"{plugin.name!r}; name the entry point the same"
                )
        except Exception as exc:  # a broken plugin must not take the others down
            why = f"{type(exc).__name__}: {exc}"
            log.warning("env plugin %s (%s) failed to load: %s", point.name, point.value, why)
            _broken[point.name] = f"{point.value}: {why}"
            continue
        _registry[plugin.name] = plugin


def known_envs() -> tuple[str, ...]:
    """Names of the registered environments."""
    _load_entry_points()
    return tuple(sorted(_registry))


def env_plugin(name: str) -> EnvPlugin:
    """The registration of environment `name`; ValueError naming the known ones."""
    _load_entry_points()
    try:
        return _registry[name]
    except (KeyError, TypeError):
        pass
    if isinstance(name, str) and name in _broken:
        raise ValueError(f"env: the plugin {name!r} failed to load ({_broken[name]})")
    known = ", ".join(known_envs())
    hint = (
        ""
        if known
        else f"; no {ENTRY_POINT_GROUP!r} entry points are installed: reinstall coexist"
        " (`make setup`) so that its own are declared"
    )
    raise ValueError(f"env: unknown environment {name!r} (known: {known}){hint}")


def get_domain(name: str) -> Domain:
    """The domain description of environment `name`."""
    return env_plugin(name).domain


def get_drawing(name: str) -> Drawing:
    """How the console draws environment `name` (`PlainDrawing` when it gives none)."""
    return env_plugin(name).drawing or PlainDrawing()


def make_env(name: str, goals: Sequence[str], **kwargs: Any) -> ParallelEnv:
    """A fresh PettingZoo env of environment `name` with one agent per goal."""
    return env_plugin(name).make_env(goals=goals, **kwargs)


def episode_resets(name: str, seed: int, episodes: int, n_agents: int) -> list[dict[str, Any]]:
    """Keyword arguments of `env.reset` for `episodes` paired episodes from `seed`: the same
    starts for every method compared on them (the plugin's `start_states`; otherwise the env's
    own start, reseeded with seed + episode)."""
    starts = env_plugin(name).start_states
    if starts is None:
        return [{"seed": seed + e} for e in range(episodes)]
    return [{"options": {"state": s}} for s in starts(seed, episodes, n_agents)]


def load_reference(reference: str, what: str) -> Any:
    """The object a `"module:attribute"` reference names (an `EnvPlugin.training`); ValueError
    naming `what` when it does not resolve."""
    module_name, _, attribute = reference.partition(":")
    if not module_name or not attribute:
        raise ValueError(f"{what}: expected 'module:attribute', got {reference!r}")
    try:
        target: Any = importlib.import_module(module_name)
        for part in attribute.split("."):
            target = getattr(target, part)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"{what}: {reference!r} does not resolve ({exc})") from None
    return target
