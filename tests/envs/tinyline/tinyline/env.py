"""The corridor as a PettingZoo `ParallelEnv`, and its `Domain`.

| property    | value                                                                   |
|-------------|-------------------------------------------------------------------------|
| agents      | `agent_0` .. `agent_{N-1}`, N = len(goals) in 1..`MAX_AGENTS`           |
| goals       | `c0` .. `c4`: stand on that cell                                        |
| actions     | Discrete(3): 0 stay, 1 left, 2 right (a move into an occupied cell or   |
|             | off the corridor stays)                                                 |
| observation | Box(N) float32: own cell / (CELLS - 1), then the others' in agent order |
| reward      | -|cell - goal cell| / (CELLS - 1) per step                             |
| termination | every agent on its goal cell                                            |
| truncation  | `max_steps`                                                             |
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

from envs.base import BlendNormalisation, DomainCounts, check_goal

CELLS = 5
MAX_AGENTS = 3
GOALS = tuple(f"c{k}" for k in range(CELLS))
MOVES = (0, -1, 1)


class Corridor(ParallelEnv):
    metadata: dict[str, Any] = {"name": "tinyline_v0"}  # noqa: RUF012

    def __init__(self, goals: Sequence[str] = ("c0", "c4"), max_steps: int = 30) -> None:
        if not 1 <= len(goals) <= MAX_AGENTS:
            raise ValueError(f"goals: expected 1..{MAX_AGENTS}, got {len(goals)}")
        self.targets = [check_goal(LINE, g, "goals") for g in goals]
        self.possible_agents = [f"agent_{i}" for i in range(len(goals))]
        self.agents: list[str] = []
        self.max_steps = max_steps
        n = len(goals)
        box = gymnasium.spaces.Box(0.0, 1.0, (n,), np.float32)
        self.observation_spaces = dict.fromkeys(self.possible_agents, box)
        self.action_spaces = {a: gymnasium.spaces.Discrete(3) for a in self.possible_agents}
        self.cells = [0] * n
        self.t = 0

    def observation_space(self, agent: str) -> gymnasium.spaces.Space:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> gymnasium.spaces.Space:
        return self.action_spaces[agent]

    def _observations(self) -> dict[str, np.ndarray]:
        scaled = [c / (CELLS - 1) for c in self.cells]
        return {
            a: np.array([scaled[i], *scaled[:i], *scaled[i + 1 :]], dtype=np.float32)
            for i, a in enumerate(self.possible_agents)
            if a in self.agents
        }

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        rng = np.random.default_rng(seed)
        self.cells = [int(c) for c in rng.choice(CELLS, len(self.possible_agents), replace=False)]
        self.agents, self.t = list(self.possible_agents), 0
        return self._observations(), {a: {} for a in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        for i, a in enumerate(self.possible_agents):
            to = self.cells[i] + MOVES[int(actions.get(a, 0))]
            if 0 <= to < CELLS and to not in self.cells:
                self.cells[i] = to
        self.t += 1
        gaps = [abs(c - t) / (CELLS - 1) for c, t in zip(self.cells, self.targets, strict=True)]
        rewards = {a: -gaps[i] for i, a in enumerate(self.possible_agents)}
        arrived = not any(gaps)
        out = self._observations()
        terminated = dict.fromkeys(self.agents, arrived)
        truncated = dict.fromkeys(self.agents, self.t >= self.max_steps and not arrived)
        infos: dict[str, dict] = {a: {} for a in self.agents}
        if arrived or self.t >= self.max_steps:
            self.agents = []
        return out, rewards, terminated, truncated, infos


class LineDomain(DomainCounts):
    """Pair views: (own cell, other cell); the partner view swaps them."""

    name = "tinyline"
    goals: tuple[str, ...] = GOALS
    action_meanings: tuple[str, ...] = ("stay", "left", "right")
    max_agents = MAX_AGENTS
    pair_obs_dim = 2
    blend_normalisation: BlendNormalisation = "standardise"
    goal_is_final = False

    def obs_dim(self, n_agents: int) -> int:
        self._check_n(n_agents)
        return n_agents

    def observation_layout(self, n_agents: int) -> list[str]:
        return ["own cell"] + [f"cell of agent {j}" for j in range(1, n_agents)]

    def task_views(self, obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
        obs_BD = np.asarray(obs_BD, dtype=np.float32).reshape(-1, n_agents)
        if n_agents == 1:  # alone: the other cell is the ego's own
            return np.stack([obs_BD[:, 0], obs_BD[:, 0]], axis=-1)[:, None]
        own_BK = np.repeat(obs_BD[:, :1], n_agents - 1, axis=1)
        return np.stack([own_BK, obs_BD[:, 1:]], axis=-1)

    def partner_view(self, obs_BD: np.ndarray, n_agents: int, partner: int) -> np.ndarray:
        obs_BD = np.asarray(obs_BD, dtype=np.float32).reshape(-1, n_agents)
        return np.stack([obs_BD[:, partner], obs_BD[:, 0]], axis=-1)

    def goal_reached(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> np.ndarray:
        cell = check_goal(self, goal) / (CELLS - 1)
        return np.isclose(np.asarray(obs_BD)[:, 0], cell)

    def goal_kept(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> None:
        return None


LINE = LineDomain()


def make_corridor(goals: Sequence[str], **kwargs: Any) -> Corridor:
    return Corridor(goals=goals, **kwargs)
