"""Coexistence particle world (paper §4.1) as a PettingZoo `ParallelEnv`.

Each agent is a point mass in the unit square with its own goal: a cell, column or row of a 5×5
grid (`envs.particle.goals`). It is rewarded for being in its *target area* and for the other
agents being in its *influence area* (the mirror image of the target area through the centre).

| property           | value                                                                  |
|--------------------|------------------------------------------------------------------------|
| import             | `from envs.particle.env import parallel_env`                           |
| agents             | `agent_0` .. `agent_{N-1}`, N = len(goals) in 1..5                     |
| actions            | Discrete(5): 0 rest, 1 up (+y), 2 down (-y), 3 left (-x), 4 right (+x) |
| observation        | Box(4N) float32: own `[x, y, vx, vy]`, then the others' blocks in      |
|                    | agent order                                                            |
| observation bounds | positions [0, 1], velocities [-0.5, 0.5] (`MAX_SPEED`)                 |
| state()            | (4N,) float32: every agent's `[x, y, vx, vy]` in agent order           |
| reward of agent i  | -dist(i, target_i) - Σ_{j≠i} dist(j, influence_i); dist = distance to  |
|                    | the area's closest point, 0 inside                                     |
| termination        | every agent inside its target area at the same step (all end together) |
| truncation         | `max_steps` steps (1000 in the paper)                                  |
| start state        | positions uniform in [0, 1]², velocities 0;                            |
|                    | or `reset(options={"state": (N, 4) array})` for paired evaluations     |
| infos              | `{"goal": goal id, "in_target": bool}` per agent                       |
| render modes       | `"rgb_array"` (480×480×3 uint8)                                        |

Constants (world.py): dt 0.1, damping 0.25, acceleration 2.0, max speed 0.5 (a side crossed from
rest in 21 steps). Dynamics and reward are the pure functions of `envs.particle.world`, stepped
through a `BatchedParticleWorld` with one world, so this env and the batched trainer simulator
cannot drift apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium.spaces import Box, Discrete
from pettingzoo import ParallelEnv

from envs.particle.batched import MAX_AGENTS, BatchedParticleWorld
from envs.particle.goals import goal_indices
from envs.particle.render import render_frame
from envs.particle.world import MAX_SPEED, N_ACTIONS, STATE_DIM, in_target, random_states


class ParticleCoexistenceEnv(ParallelEnv[str, np.ndarray, int]):
    """N agents with independent goals in the particle world; see the module docstring."""

    metadata: dict[str, Any] = {  # noqa: RUF012 (PettingZoo's class attribute)
        "name": "particle_coexistence_v0",
        "render_modes": ["rgb_array"],
        "render_fps": 20,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        goals: Sequence[str] = ("a2", "b3"),
        max_steps: int = 1000,
        render_mode: str | None = None,
    ) -> None:
        if isinstance(goals, str) or not 1 <= len(goals) <= MAX_AGENTS:
            raise ValueError(f"goals: expected 1..{MAX_AGENTS} goal ids, got {goals!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode: expected None or 'rgb_array', got {render_mode!r}")
        self.goals: tuple[str, ...] = tuple(goals)
        self._goals_N = goal_indices(self.goals)
        self.max_steps = max_steps
        self.render_mode = render_mode
        self.possible_agents = [f"agent_{i}" for i in range(len(self.goals))]
        self.agents: list[str] = []
        self._world = BatchedParticleWorld(self._goals_N[None], max_steps=max_steps, seed=0)
        self._rng = np.random.default_rng()

        n = len(self.goals)
        low = np.tile(np.array([0.0, 0.0, -MAX_SPEED, -MAX_SPEED], dtype=np.float32), n)
        high = np.tile(np.array([1.0, 1.0, MAX_SPEED, MAX_SPEED], dtype=np.float32), n)
        # One space object per agent, built once: the API test wants the same object each call.
        self._observation_spaces = {
            a: Box(low, high, dtype=np.float32) for a in self.possible_agents
        }
        self._action_spaces = {a: Discrete(N_ACTIONS) for a in self.possible_agents}

    def observation_space(self, agent: str) -> Box:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> Discrete:
        return self._action_spaces[agent]

    def _start_state(self, options: dict[str, Any] | None) -> np.ndarray:
        n = len(self.goals)
        if options is None or options.get("state") is None:
            return random_states(self._rng, 1, n)
        state = np.asarray(options["state"], dtype=np.float64)
        if state.shape != (n, STATE_DIM):
            raise ValueError(f'options["state"]: expected shape ({n}, 4), got {state.shape}')
        if not np.all(np.isfinite(state)):
            raise ValueError('options["state"]: expected finite values')
        pos, vel = state[:, :2], state[:, 2:]
        if np.any(pos < 0.0) or np.any(pos > 1.0):
            raise ValueError('options["state"]: positions must lie in [0, 1]')
        if np.any(np.linalg.norm(vel, axis=1) > MAX_SPEED + 1e-9):
            raise ValueError(f'options["state"]: speeds must be at most {MAX_SPEED}')
        return state[None]

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        obs_1ND = self._world.reset(self._start_state(options))
        self.agents = self.possible_agents[:]
        return self._per_agent(obs_1ND[0]), self._infos()

    def _per_agent(self, rows_N: np.ndarray) -> dict[str, Any]:
        return {a: rows_N[i] for i, a in enumerate(self.possible_agents)}

    def _infos(self) -> dict[str, dict[str, Any]]:
        inside_N = in_target(self._world.state[0], self._goals_N)
        return {
            a: {"goal": self.goals[i], "in_target": bool(inside_N[i])}
            for i, a in enumerate(self.possible_agents)
        }

    def step(
        self, actions: dict[str, int]
    ) -> tuple[
        dict[str, np.ndarray],
        dict[str, float],
        dict[str, bool],
        dict[str, bool],
        dict[str, dict[str, Any]],
    ]:
        if not self.agents:
            raise ValueError("step: the episode is over (or never started); call reset() first")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"actions: missing an action for {', '.join(missing)}")
        actions_1N = np.array([[int(actions[a]) for a in self.possible_agents]], dtype=np.int64)
        if np.any(actions_1N < 0) or np.any(actions_1N >= N_ACTIONS):
            raise ValueError(f"actions: expected values in 0..{N_ACTIONS - 1}, got {actions}")
        result = self._world.step(actions_1N)
        obs = self._per_agent(result.next_obs_BND[0])
        rewards = {a: float(r) for a, r in self._per_agent(result.rewards_BN[0]).items()}
        terminated = dict.fromkeys(self.agents, bool(result.terminated_B[0]))
        truncated = dict.fromkeys(self.agents, bool(result.truncated_B[0]))
        infos = self._infos()
        if result.terminated_B[0] or result.truncated_B[0]:
            self.agents = []
        return obs, rewards, terminated, truncated, infos

    def state(self) -> np.ndarray:
        return self._world.state[0].reshape(-1).astype(np.float32)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() needs render_mode='rgb_array' at construction")
            return None
        return render_frame(self._world.state[0], self.goals)

    def close(self) -> None:
        pass


def parallel_env(**kwargs: Any) -> ParticleCoexistenceEnv:
    """Factory in PettingZoo's style: `parallel_env(goals=("a2", "b3"))`."""
    return ParticleCoexistenceEnv(**kwargs)
