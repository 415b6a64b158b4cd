"""Environments by name: the domain description and a PettingZoo env factory for each.

| name       | domain               | env                                      |
|------------|----------------------|------------------------------------------|
| `particle` | `envs.particle.PARTICLE` | `envs.particle.ParticleCoexistenceEnv` |
| `cooking`  | `envs.cooking.COOKING`   | `envs.cooking.CookingEnv` (goals = recipes) |

To add an environment, add one entry to `_REGISTRY` (a domain and a factory taking the goals).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

from pettingzoo import ParallelEnv

from envs.base import Domain
from envs.cooking import COOKING, make_cooking_env
from envs.particle import PARTICLE, ParticleCoexistenceEnv


class _Entry(NamedTuple):
    domain: Domain
    make_env: Callable[..., ParallelEnv]


_REGISTRY: dict[str, _Entry] = {
    "particle": _Entry(PARTICLE, ParticleCoexistenceEnv),
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
