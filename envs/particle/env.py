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

from envs.parallel import OneWorldEnv
from envs.particle.batched import MAX_AGENTS, BatchedParticleWorld
from envs.particle.goals import goal_indices
from envs.particle.render import render_frame
from envs.particle.world import MAX_SPEED, N_ACTIONS, STATE_DIM, in_target, random_states


class ParticleCoexistenceEnv(OneWorldEnv):
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
        n = len(goals)
        low = np.tile(np.array([0.0, 0.0, -MAX_SPEED, -MAX_SPEED], dtype=np.float32), n)
        high = np.tile(np.array([1.0, 1.0, MAX_SPEED, MAX_SPEED], dtype=np.float32), n)
        self._setup_agents(n, low, high, N_ACTIONS, render_mode)
        self.goals: tuple[str, ...] = tuple(goals)
        self._goals_N = goal_indices(self.goals)
        self.max_steps = max_steps
        self.world: BatchedParticleWorld = BatchedParticleWorld(
            self._goals_N[None], max_steps=max_steps, seed=0
        )
        self._rng = np.random.default_rng()

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
        return self._started(self.world.reset(self._start_state(options)))

    def _infos(self) -> dict[str, dict[str, Any]]:
        inside_N = in_target(self.world.state[0], self._goals_N)
        return {
            a: {"goal": self.goals[i], "in_target": bool(inside_N[i])}
            for i, a in enumerate(self.possible_agents)
        }

    def state(self) -> np.ndarray:
        return self.world.state[0].reshape(-1).astype(np.float32)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() needs render_mode='rgb_array' at construction")
            return None
        return render_frame(self.world.state[0], self.goals)


def parallel_env(**kwargs: Any) -> ParticleCoexistenceEnv:
    """Factory in PettingZoo's style: `parallel_env(goals=("a2", "b3"))`."""
    return ParticleCoexistenceEnv(**kwargs)
