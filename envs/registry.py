"""Environments by name: the domain description and a PettingZoo env factory for each.

| name       | domain               | env                                      |
|------------|----------------------|------------------------------------------|
| `particle` | `envs.particle.PARTICLE` | `envs.particle.ParticleCoexistenceEnv` |
| `cooking`  | `envs.cooking.COOKING`   | `envs.cooking.CookingEnv` (goals = recipes) |

To add an environment, add one entry to `_REGISTRY` (a domain, a factory taking the goals, and
optionally how paired episodes start: `episode_resets`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

from pettingzoo import ParallelEnv

from envs.base import Domain
from envs.cooking import COOKING, make_cooking_env
from envs.particle import PARTICLE, ParticleCoexistenceEnv
from envs.particle.scenarios import start_states


class _Entry(NamedTuple):
    domain: Domain
    make_env: Callable[..., ParallelEnv]
    # (seed, episodes, n_agents) -> each episode's start state, for `reset(options={"state"})`;
    # None: the env's own start (`reset(seed=...)`)
    start_states: Callable[[int, int, int], Any] | None = None


_REGISTRY: dict[str, _Entry] = {
    "particle": _Entry(PARTICLE, ParticleCoexistenceEnv, start_states),
    "cooking": _Entry(COOKING, make_cooking_env),
}


def known_envs() -> tuple[str, ...]:
    """Names of the registered environments."""
    return tuple(sorted(_REGISTRY))


def _entry(name: str) -> _Entry:
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"env: unknown environment {name!r} (known: {', '.join(known_envs())})"
        ) from None


def get_domain(name: str) -> Domain:
    """The domain description of environment `name`."""
    return _entry(name).domain


def make_env(name: str, goals: Sequence[str], **kwargs: Any) -> ParallelEnv:
    """A fresh PettingZoo env of environment `name` with one agent per goal."""
    return _entry(name).make_env(goals=goals, **kwargs)


def episode_resets(name: str, seed: int, episodes: int, n_agents: int) -> list[dict[str, Any]]:
    """Keyword arguments of `env.reset` for `episodes` paired episodes from `seed`: the same
    starts for every method compared on them (particle: `start_states`; otherwise the env's own
    start, reseeded with seed + episode)."""
    starts = _entry(name).start_states
    if starts is None:
        return [{"seed": seed + e} for e in range(episodes)]
    return [{"options": {"state": s}} for s in starts(seed, episodes, n_agents)]
