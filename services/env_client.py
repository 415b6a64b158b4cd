"""The environment client: episodes of any registered env in which every agent acts through a
policy server (`coexist_client.RemotePolicy`).

| agent            | policy                                  | request per step                     |
|------------------|-----------------------------------------|--------------------------------------|
| 0 (the ego)      | `method` (aail_bounded by default) with | its observation, partners 1..N-1 with|
|                  | every other agent as a partner, its goal| their goals (or `infer`: none, the   |
|                  | announced or (`infer`) inferred         | server infers them from the actions) |
| j = 1..N-1       | its own task policy (`sl`), the agent   | agent j's own observation (the env's |
|                  | as the ego of its own request           | perspective), no partners            |

So the client needs no local models: each agent holds one episode session of the SDK (a gRPC
`Episode` stream, or `POST /v1/act` per step over HTTP, a REST session where goals are inferred;
all seed step t with seed + t, so the transports give the same episodes).

Seeding: start states are `envs.registry.episode_resets(env, seed, episodes, N)` (paired across
methods: the particle world's `start_states`, the kitchen's own layout); agent i's sampling seed
in episode e is drawn from `SeedSequence([seed, e, i])`. Agents act on the *sampled* action
(the Boltzmann policy, as in training) unless `greedy`.

Returned per episode (`EpisodeResult`): each agent's return (sum of its rewards), whether its own
goal is reached at the last step (`success`: `Domain.goal_reached` on its final observation: in
its target area, its dish served), and the length. `summarise` gives mean ± standard error over
episodes (SE = sample std / sqrt(n), 0 for one episode).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from coexist_client import Client, RemotePolicy

from envs.base import check_goal
from envs.registry import episode_resets, get_domain, make_env


@dataclass(frozen=True)
class EpisodeResult:
    episode: int
    goals: tuple[str, ...]  # agent 0 is the ego
    returns: tuple[float, ...]  # one per agent
    success: tuple[bool, ...]  # its own goal reached at the last step
    length: int
    frames: tuple[np.ndarray, ...] = ()  # RGB frames when recorded

    @property
    def team_return(self) -> float:
        return float(sum(self.returns))


@dataclass(frozen=True)
class MeanSE:
    mean: float
    se: float

    def __str__(self) -> str:
        return f"{self.mean:.2f} ± {self.se:.2f}"


def mean_se(values: Sequence[float]) -> MeanSE:
    """Mean and its standard error (sample std / sqrt(n); 0 when n = 1)."""
    if not values:
        raise ValueError("values: expected at least one value")
    array = np.asarray(values, dtype=np.float64)
    se = float(array.std(ddof=1) / math.sqrt(len(array))) if len(array) > 1 else 0.0
    return MeanSE(float(array.mean()), se)


@dataclass(frozen=True)
class Summary:
    returns: tuple[MeanSE, ...]  # per agent
    success_rate: tuple[float, ...]  # per agent
    team_return: MeanSE
    length: MeanSE


def summarise(results: Sequence[EpisodeResult]) -> Summary:
    n_agents = len(results[0].returns)
    return Summary(
        returns=tuple(mean_se([r.returns[i] for r in results]) for i in range(n_agents)),
        success_rate=tuple(
            float(np.mean([r.success[i] for r in results])) for i in range(n_agents)
        ),
        team_return=mean_se([r.team_return for r in results]),
        length=mean_se([float(r.length) for r in results]),
    )


def agent_seed(seed: int, episode: int, agent: int) -> int:
    """Sampling seed of `agent` in `episode` (independent streams, reproducible from `seed`)."""
    return int(np.random.SeedSequence([seed, episode, agent]).generate_state(1)[0])


def run_episodes(
    client: Client,
    *,
    ego_goal: str,
    partner_goals: Sequence[str],
    env: str = "particle",
    method: str = "aail_bounded",
    regret_bound: float | None = None,
    budget: float | None = None,
    infer: bool = False,
    episodes: int = 20,
    seed: int = 0,
    max_steps: int = 200,
    alias: str = "production",
    greedy: bool = False,
    record_first: bool = False,
    on_episode: Callable[[EpisodeResult], None] | None = None,
) -> list[EpisodeResult]:
    """Run `episodes` episodes of `env`; see the module docstring. `infer`: the ego is told no
    partner goal. `record_first` keeps episode 0's frames."""
    domain = get_domain(env)
    if episodes < 1:
        raise ValueError(f"episodes: expected >= 1, got {episodes}")
    if max_steps < 1:
        raise ValueError(f"max_steps: expected >= 1, got {max_steps}")
    goals = (ego_goal, *partner_goals)
    check_goal(domain, ego_goal, "ego_goal")
    for k, goal in enumerate(partner_goals):
        check_goal(domain, goal, f"partner_goals[{k}]")
    if len(goals) > domain.max_agents:
        raise ValueError(f"partner_goals: expected at most {domain.max_agents - 1} partners")
    policies = [
        RemotePolicy(
            client,
            env,
            goals,
            i,
            method=method if i == 0 else "sl",
            infer=infer,
            greedy=greedy,
            alias=alias,
            regret_bound=regret_bound if i == 0 else None,
            budget=budget if i == 0 else None,
        )
        for i in range(len(goals))
    ]
    resets = episode_resets(env, seed, episodes, len(goals))
    results = []
    try:
        for e in range(episodes):
            for i, policy in enumerate(policies):
                policy.reset(seed=agent_seed(seed, e, i))
            result = _run_one(
                env,
                goals,
                policies,
                resets[e],
                episode=e,
                max_steps=max_steps,
                record=record_first and e == 0,
            )
            results.append(result)
            if on_episode is not None:
                on_episode(result)
    finally:
        for policy in policies:
            policy.close()
    return results


def _run_one(
    env_name: str,
    goals: tuple[str, ...],
    policies: Sequence[RemotePolicy],
    reset: dict[str, Any],
    *,
    episode: int,
    max_steps: int,
    record: bool,
) -> EpisodeResult:
    # render_mode only when frames are recorded: a plugin's factory need not take it otherwise
    rendering = {"render_mode": "rgb_array"} if record else {}
    env = make_env(env_name, goals, max_steps=max_steps, **rendering)
    domain, agents = get_domain(env_name), env.possible_agents
    observations, _ = env.reset(**reset)
    frames = [env.render()] if record else []
    returns = np.zeros(len(goals))
    length = 0
    actions: dict[str, int] = {}
    while env.agents:
        # the partners' actions of the previous step: what an inferring ego observed
        observed = {k: actions[agent] for k, agent in enumerate(agents)} if actions else None
        actions = {
            agent: policies[i](observations[agent], observed) for i, agent in enumerate(agents)
        }
        observations, rewards, _, _, _ = env.step(actions)
        returns += [rewards[a] for a in agents]
        length += 1
        if record:
            frames.append(env.render())
    n = len(agents)
    success = []
    for i, agent in enumerate(agents):
        reached = domain.goal_reached(np.asarray(observations[agent])[None], n, goals[i])
        success.append(reached is not None and bool(reached[0]))
    env.close()
    return EpisodeResult(
        episode=episode,
        goals=goals,
        returns=tuple(float(r) for r in returns),
        success=tuple(success),
        length=length,
        frames=tuple(f for f in frames if f is not None),
    )
