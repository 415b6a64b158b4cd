"""The environment client: particle episodes in which every agent acts through a policy server.

| agent            | policy                                  | request per step                     |
|------------------|-----------------------------------------|--------------------------------------|
| 0 (the ego)      | `method` (aail by default) with every   | its observation, partners 1..N-1 with|
|                  | other agent as an announced partner     | their goals                          |
| j = 1..N-1       | its own task policy (`sl`), the agent   | agent j's own observation (the env's |
|                  | as the ego of its own request           | perspective), no partners            |

So the client needs no local models: each agent holds one episode session of the SDK (a gRPC
`Episode` stream, or `POST /v1/act` per step over HTTP; both seed step t with seed + t, so the two
transports give the same episodes).

Seeding: start states are `envs.particle.scenarios.start_states(seed, episodes, N)` (paired across
methods); agent i's sampling seed in episode e is drawn from `SeedSequence([seed, e, i])`.
Agents act on the *sampled* action (the Boltzmann policy, as in training) unless `greedy`.

Returned per episode (`EpisodeResult`): each agent's return (sum of its rewards), whether it ends
the episode inside its own target area (`success`), and the length. `summarise` gives mean ±
standard error over episodes (SE = sample std / sqrt(n), 0 for one episode).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from envs.base import check_goal
from envs.particle.domain import PARTICLE
from envs.particle.env import ParticleCoexistenceEnv
from envs.particle.scenarios import start_states
from services.sdk.types import Action

SUPPORTED_ENVS = ("particle",)


class EpisodeSession(Protocol):
    """An SDK episode session (`HttpEpisode`, `GrpcEpisode`)."""

    def act(self, observation: Any = None) -> Action: ...
    def __enter__(self) -> Any: ...
    def __exit__(self, *exc_info: Any) -> Any: ...


class EpisodeClient(Protocol):
    """Any SDK client: `CoexistClient` or `GrpcCoexistClient`."""

    def episode(
        self,
        env: str,
        ego_goal: str,
        *,
        partners: Any = None,
        method: str = "aail_bounded",
        regret_bound: float | None = None,
        seed: int | None = None,
        alias: str = "production",
    ) -> EpisodeSession: ...


@dataclass(frozen=True)
class EpisodeResult:
    episode: int
    goals: tuple[str, ...]  # agent 0 is the ego
    returns: tuple[float, ...]  # one per agent
    success: tuple[bool, ...]  # inside its own target area at the last step
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
    client: EpisodeClient,
    *,
    ego_goal: str,
    partner_goals: Sequence[str],
    env: str = "particle",
    method: str = "aail_bounded",
    regret_bound: float | None = None,
    episodes: int = 20,
    seed: int = 0,
    max_steps: int = 200,
    alias: str = "production",
    greedy: bool = False,
    record_first: bool = False,
    on_episode: Callable[[EpisodeResult], None] | None = None,
) -> list[EpisodeResult]:
    """Run `episodes` episodes; see the module docstring. `record_first` keeps episode 0's frames."""
    if env not in SUPPORTED_ENVS:
        raise ValueError(f"env: expected one of {SUPPORTED_ENVS}, got {env!r}")
    if episodes < 1:
        raise ValueError(f"episodes: expected >= 1, got {episodes}")
    if max_steps < 1:
        raise ValueError(f"max_steps: expected >= 1, got {max_steps}")
    goals = (ego_goal, *partner_goals)
    check_goal(PARTICLE, ego_goal, "ego_goal")
    for k, goal in enumerate(partner_goals):
        check_goal(PARTICLE, goal, f"partner_goals[{k}]")
    if len(goals) > PARTICLE.max_agents:
        raise ValueError(f"partner_goals: expected at most {PARTICLE.max_agents - 1} partners")
    starts_ENS = start_states(seed, episodes, len(goals))
    results = []
    for e in range(episodes):
        record = record_first and e == 0
        result = _run_one(
            client, env, goals, method, alias, starts_ENS[e], agent_seeds=[
                agent_seed(seed, e, i) for i in range(len(goals))
            ], episode=e, max_steps=max_steps, greedy=greedy, record=record,
            regret_bound=regret_bound,
        )  # fmt: skip
        results.append(result)
        if on_episode is not None:
            on_episode(result)
    return results


def _run_one(
    client: EpisodeClient,
    env_name: str,
    goals: tuple[str, ...],
    method: str,
    alias: str,
    start_N4: np.ndarray,
    *,
    agent_seeds: Sequence[int],
    episode: int,
    max_steps: int,
    greedy: bool,
    record: bool,
    regret_bound: float | None = None,
) -> EpisodeResult:
    env = ParticleCoexistenceEnv(
        goals=goals, max_steps=max_steps, render_mode="rgb_array" if record else None
    )
    agents = env.possible_agents
    partners = {j: goals[j] for j in range(1, len(goals))}
    with ExitStack() as stack:
        sessions = [
            stack.enter_context(
                client.episode(
                    env_name, goal, partners=partners if i == 0 else None,
                    method=method if i == 0 else "sl", seed=agent_seeds[i], alias=alias,
                    regret_bound=regret_bound if i == 0 else None,
                )
            )
            for i, goal in enumerate(goals)
        ]  # fmt: skip
        observations, infos = env.reset(options={"state": start_N4})
        frames = [env.render()] if record else []
        returns = np.zeros(len(goals))
        length = 0
        while env.agents:
            actions = {}
            for i, agent in enumerate(agents):
                answer = sessions[i].act(observations[agent])
                actions[agent] = answer.greedy_action if greedy else answer.action
            observations, rewards, _, _, infos = env.step(actions)
            returns += [rewards[a] for a in agents]
            length += 1
            if record:
                frames.append(env.render())
    return EpisodeResult(
        episode=episode,
        goals=goals,
        returns=tuple(float(r) for r in returns),
        success=tuple(bool(infos[a]["in_target"]) for a in agents),
        length=length,
        frames=tuple(f for f in frames if f is not None),
    )
