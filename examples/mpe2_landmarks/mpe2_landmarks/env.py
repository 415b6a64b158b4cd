"""The environment as a PettingZoo `ParallelEnv` over an MPE2 `World`, and its `Domain`.

| property    | value                                                                    |
|-------------|--------------------------------------------------------------------------|
| agents      | `agent_0` .. `agent_{N-1}`, N = len(goals) in 1..`MAX_AGENTS`            |
| goals       | `l0` .. `l3`: reach that landmark (`LANDMARKS`, the corners of a square) |
| actions     | Discrete(5): 0 rest, 1 left, 2 right, 3 down, 4 up (force `ACCEL`)        |
| observation | Box(4N) float32: own `[x, y, vx, vy]`, then the others' in agent order   |
| reward      | minus the distance to the agent's landmark, per step                     |
| termination | every agent within `REACHED` of its landmark                             |
| truncation  | `max_steps`                                                              |
| physics     | MPE2's: dt 0.1, damping 0.25, agents of radius `AGENT_SIZE` that collide |
| start       | positions uniform in [-1, 1]², at rest, drawn from `reset`'s seed        |
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from mpe2._mpe_utils.core import Agent, World
from pettingzoo import ParallelEnv

from envs.base import BlendNormalisation, DomainCounts, check_goal

LANDMARKS = np.array([(-0.6, -0.6), (0.6, -0.6), (-0.6, 0.6), (0.6, 0.6)])
GOALS = tuple(f"l{k}" for k in range(len(LANDMARKS)))
MAX_AGENTS = 3
AGENT_SIZE = 0.15
ACCEL = 5.0  # MPE2's default action sensitivity
REACHED = 0.1
DIRECTIONS = np.array([(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)], dtype=np.float64)
SPEED_BOUND = 3.0  # the observation space's bound on a velocity (forces and damping keep it under)
DT, DAMPING = 0.1, 0.25  # MPE2 World's step and damping (agents of mass 1, no speed limit)


class LandmarksEnv(ParallelEnv):
    metadata: dict[str, Any] = {"name": "mpe2_landmarks_v0"}  # noqa: RUF012

    def __init__(self, goals: Sequence[str] = ("l0", "l3"), max_steps: int = 100) -> None:
        if not 1 <= len(goals) <= MAX_AGENTS:
            raise ValueError(f"goals: expected 1..{MAX_AGENTS}, got {len(goals)}")
        self.targets = [check_goal(LANDMARKS_DOMAIN, g, "goals") for g in goals]
        self.goals = tuple(goals)
        self.possible_agents = [f"agent_{i}" for i in range(len(goals))]
        self.agents: list[str] = []
        self.max_steps = max_steps
        n = len(goals)
        bound = np.tile(np.array([1.5, 1.5, SPEED_BOUND, SPEED_BOUND], dtype=np.float32), n)
        box = gymnasium.spaces.Box(-bound, bound, dtype=np.float32)
        self.observation_spaces = dict.fromkeys(self.possible_agents, box)
        self.action_spaces = {a: gymnasium.spaces.Discrete(5) for a in self.possible_agents}
        self.world = World()
        self.world.agents = [Agent() for _ in range(n)]
        for i, agent in enumerate(self.world.agents):
            agent.name, agent.size, agent.collide, agent.silent = (
                f"agent_{i}",
                AGENT_SIZE,
                True,
                True,
            )
        self.t = 0

    def observation_space(self, agent: str) -> gymnasium.spaces.Space:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> gymnasium.spaces.Space:
        return self.action_spaces[agent]

    def _states(self) -> np.ndarray:
        """(N, 4): every agent's position and velocity."""
        return np.array([[*a.state.p_pos, *a.state.p_vel] for a in self.world.agents])

    def _observations(self) -> dict[str, np.ndarray]:
        states = self._states()
        order = range(len(states))
        return {
            name: np.concatenate([states[i], *(states[j] for j in order if j != i)])
            .clip(-self.observation_spaces[name].high, self.observation_spaces[name].high)
            .astype(np.float32)
            for i, name in enumerate(self.possible_agents)
            if name in self.agents
        }

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        rng = np.random.default_rng(seed)
        for agent in self.world.agents:
            agent.state.p_pos = rng.uniform(-1.0, 1.0, 2)
            agent.state.p_vel = np.zeros(2)
            agent.state.c = np.zeros(0)
        self.agents, self.t = list(self.possible_agents), 0
        return self._observations(), {a: {} for a in self.agents}

    def _gaps(self) -> np.ndarray:
        positions = np.array([a.state.p_pos for a in self.world.agents])
        return np.linalg.norm(positions - LANDMARKS[self.targets], axis=1)

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        for name, agent in zip(self.possible_agents, self.world.agents, strict=True):
            agent.action.u = DIRECTIONS[int(actions.get(name, 0))] * ACCEL
            agent.action.c = np.zeros(0)
        self.world.step()
        self.t += 1
        gaps = self._gaps()
        rewards = {a: float(-gaps[i]) for i, a in enumerate(self.possible_agents)}
        arrived = bool((gaps < REACHED).all())
        out = self._observations()
        terminated = dict.fromkeys(self.agents, arrived)
        truncated = dict.fromkeys(self.agents, self.t >= self.max_steps and not arrived)
        infos: dict[str, dict] = {a: {} for a in self.agents}
        if arrived or self.t >= self.max_steps:
            self.agents = []
        return out, rewards, terminated, truncated, infos


class LandmarksDomain(DomainCounts):
    """Pair views: (own x, y, vx, vy, other's x, y, vx, vy); the partner view swaps them."""

    name = "mpe2_landmarks"
    goals: tuple[str, ...] = GOALS
    action_meanings: tuple[str, ...] = ("rest", "left", "right", "down", "up")
    max_agents = MAX_AGENTS
    pair_obs_dim = 8
    blend_normalisation: BlendNormalisation = "standardise"
    goal_is_final = False

    def obs_dim(self, n_agents: int) -> int:
        self._check_n(n_agents)
        return 4 * n_agents

    def observation_layout(self, n_agents: int) -> list[str]:
        who = ["own"] + [f"agent {j}" for j in range(1, n_agents)]
        return [f"{w} {f}" for w in who for f in ("x", "y", "vx", "vy")]

    def _blocks(self, obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
        return np.asarray(obs_BD, dtype=np.float32).reshape(-1, n_agents, 4)

    def task_views(self, obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
        blocks = self._blocks(obs_BD, n_agents)
        others = blocks[:, 1:] if n_agents > 1 else blocks[:, :1]  # alone: itself as the other
        own = np.repeat(blocks[:, :1], others.shape[1], axis=1)
        return np.concatenate([own, others], axis=-1)

    def partner_view(self, obs_BD: np.ndarray, n_agents: int, partner: int) -> np.ndarray:
        blocks = self._blocks(obs_BD, n_agents)
        return np.concatenate([blocks[:, partner], blocks[:, 0]], axis=-1)

    def goal_reached(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> np.ndarray:
        landmark = LANDMARKS[check_goal(self, goal)]
        own = np.asarray(obs_BD, dtype=np.float64)[:, :2]
        return np.linalg.norm(own - landmark, axis=1) < REACHED

    def goal_kept(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> np.ndarray:
        """(B, 5) bool: after the action, and wherever resting from then on lets it coast, the
        agent is still within `REACHED` of its landmark. MPE2's step moves the agent with its
        current velocity, then damps it and adds the action: p' = p + dt v, v' = (1 - damping) v
        + dt a. Resting then coasts a further dt v' / damping along a straight line, so the two
        ends decide (the disc is convex). Collisions are left out: the agent's own dynamics."""
        landmark = LANDMARKS[check_goal(self, goal)]
        own = np.asarray(obs_BD, dtype=np.float64)[:, :4]
        p_B12 = own[:, None, :2] + DT * own[:, None, 2:]
        v_BA2 = own[:, None, 2:] * (1.0 - DAMPING) + DIRECTIONS[None] * (ACCEL * DT)
        rest_BA2 = p_B12 + DT * v_BA2 / DAMPING
        near_B1 = np.linalg.norm(p_B12 - landmark, axis=-1) < REACHED
        return near_B1 & (np.linalg.norm(rest_BA2 - landmark, axis=-1) < REACHED)


LANDMARKS_DOMAIN = LandmarksDomain()


def make_landmarks_env(goals: Sequence[str], **kwargs: Any) -> LandmarksEnv:
    return LandmarksEnv(goals=goals, **kwargs)
