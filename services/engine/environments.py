"""Per-environment facts the engine needs, computed once: the domain, observation length -> agent
count, model names per goal, and how to build the ego's observation from a global state.

| name                         | what                                                           |
|------------------------------|----------------------------------------------------------------|
| `EnvRuntime`                 | one environment's domain plus look-up tables for the hot path  |
| `env_runtime(name)`          | the cached `EnvRuntime`, or `InvalidRequest("env")`            |
| `observations_from_states`   | global states (B, N, S) + ego index -> ego observations (B, D) |

State input comes with the environment's registration (`envs.registry.StateAdapter`), not on
the `Domain`: the domain contract is about views of an *observation*, and only the transports
need the state form. An environment without one takes observations only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np

from envs.base import Domain
from envs.registry import StateAdapter, env_plugin
from model_store.errors import InvalidArgument, brief
from model_store.naming import impact_model_name, task_model_name
from services.engine.errors import InvalidRequest
from services.engine.messages import METHODS, EnvInfo


def _model_name(make: Callable[[str, str], str], env: str, goal: str) -> str:
    try:
        return make(env, goal)
    except InvalidArgument:  # a goal that no model name can hold (e.g. all digits)
        kind = "task" if make is task_model_name else "impact"
        return f"{env}/{kind}/{goal}"


@dataclass(frozen=True)
class EnvRuntime:
    domain: Domain
    state_adapter: StateAdapter | None
    goals: frozenset[str]
    agents_by_obs_dim: dict[int, int]  # observation length -> number of agents
    task_names: dict[str, str]  # goal -> `{env}/task/{goal}`
    impact_names: dict[str, str]  # goal -> `{env}/impact/{goal}`
    info: EnvInfo


@cache
def _build_runtime(name: str) -> EnvRuntime:
    plugin = env_plugin(name)
    domain, adapter = plugin.domain, plugin.state_adapter
    counts = range(1, domain.max_agents + 1)
    obs_dims = {n: domain.obs_dim(n) for n in counts}
    info = EnvInfo(
        name=domain.name,
        goals=tuple(domain.goals),
        action_meanings=tuple(domain.action_meanings),
        max_agents=domain.max_agents,
        obs_dims=obs_dims,
        observation_layouts={n: domain.observation_layout(n) for n in counts},
        state_layout=adapter.features if adapter else None,
        pair_obs_dim=domain.pair_obs_dim,
        methods=METHODS,
    )
    by_dim: dict[int, int] = {}
    for n, dim in obs_dims.items():
        by_dim.setdefault(dim, n)
    return EnvRuntime(
        domain=domain,
        state_adapter=adapter,
        goals=frozenset(domain.goals),
        agents_by_obs_dim=by_dim,
        task_names={g: _model_name(task_model_name, name, g) for g in domain.goals},
        impact_names={g: _model_name(impact_model_name, name, g) for g in domain.goals},
        info=info,
    )


def env_runtime(name: object) -> EnvRuntime:
    """The runtime of env `name`, or `InvalidRequest` on field `env`."""
    if not isinstance(name, str):
        raise InvalidRequest("env", f"unknown environment {brief(name)} (expected a string)")
    try:
        return _build_runtime(name)
    except ValueError as exc:
        raise InvalidRequest("env", str(exc).removeprefix("env: ")) from None


def observations_from_states(
    env: str, states: object, ego_index: object, *, field: str = "states"
) -> np.ndarray:
    """The ego's observations (B, D) from global states (B, N, S) and the ego's agent index.

    The ego's layout puts its own row first and the others in agent order, so in that layout
    agent j is at position j + 1 for j < ego_index and at j for j > ego_index.
    """
    runtime = env_runtime(env)
    adapter = runtime.state_adapter
    if adapter is None:
        raise InvalidRequest(
            field,
            f"env {brief(env)} takes observations only, not global states (its state is not one row "
            "per agent): send observation / observations (layout: GET /v1/envs)",
        )
    try:
        states_BNS = np.asarray(states, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidRequest(
            field, "expected equal-length rows of numbers (every state the same agent count)"
        ) from None
    n_features = len(adapter.features)
    max_agents = runtime.domain.max_agents
    if states_BNS.ndim != 3 or states_BNS.shape[2] != n_features or states_BNS.shape[0] == 0:
        raise InvalidRequest(
            field, f"expected shape (B, N, {n_features}) with B >= 1, got {states_BNS.shape}"
        )
    n_agents = states_BNS.shape[1]
    if not 1 <= n_agents <= max_agents:
        raise InvalidRequest(field, f"expected 1..{max_agents} agents, got {n_agents}")
    finite_B = np.isfinite(states_BNS).all(axis=(1, 2))
    if not finite_B.all():
        row = int(np.argmin(finite_B))
        raise InvalidRequest(f"{field}[{row}]", "holds NaN or inf")
    if isinstance(ego_index, bool) or not isinstance(ego_index, int | np.integer):
        raise InvalidRequest("ego_index", f"expected an integer, got {brief(ego_index)}")
    if not 0 <= ego_index < n_agents:
        raise InvalidRequest("ego_index", f"expected 0..{n_agents - 1}, got {brief(ego_index)}")
    return adapter.observations(states_BNS)[:, int(ego_index), :]
