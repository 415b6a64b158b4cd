"""The PettingZoo face of a domain's batched simulator: a `ParallelEnv` that steps one world
(B = 1) of `envs.batched`, so the env and the trainer's vectorised rollouts cannot drift apart.

A domain's env subclasses `OneWorldEnv` and provides the world (`self.world`, any simulator
whose `step(actions_BN)` returns an `envs.batched.StepResult`), `_infos()` (its per-agent
infos), `state()` and `render()`; this class holds what PettingZoo asks of every env alike:
one space object per agent, the action checks, the step's dictionaries and the episode's end
(every agent ends together: the worlds terminate or truncate as a whole).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from gymnasium.spaces import Box, Discrete
from pettingzoo import ParallelEnv

from envs.batched import StepResult


class SteppedWorld(Protocol):
    def step(self, actions_BN: np.ndarray) -> StepResult: ...


class OneWorldEnv(ParallelEnv[str, np.ndarray, int]):
    """N agents in one world of a batched simulator; see the module docstring."""

    world: SteppedWorld

    def _setup_agents(
        self,
        n_agents: int,
        low_D: np.ndarray,
        high_D: np.ndarray,
        n_actions: int,
        render_mode: str | None,
    ) -> None:
        """The agents' names and spaces (observations bounded by `low_D`/`high_D`, float32)."""
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode: expected None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.n_actions = n_actions
        self.possible_agents = [f"agent_{i}" for i in range(n_agents)]
        self.agents: list[str] = []
        # One space object per agent, built once: the API test wants the same object each call.
        self._observation_spaces = {
            a: Box(low_D, high_D, dtype=np.float32) for a in self.possible_agents
        }
        self._action_spaces = {a: Discrete(n_actions) for a in self.possible_agents}

    def observation_space(self, agent: str) -> Box:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> Discrete:
        return self._action_spaces[agent]

    def _per_agent(self, rows_N: np.ndarray) -> dict[str, Any]:
        return {a: rows_N[i] for i, a in enumerate(self.possible_agents)}

    def _infos(self) -> dict[str, dict[str, Any]]:
        raise NotImplementedError

    def _started(self, obs_1ND: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """`reset`'s answer for a world just reset to `obs_1ND`; every agent is in play."""
        self.agents = self.possible_agents[:]
        return self._per_agent(obs_1ND[0]), self._infos()

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
        if np.any(actions_1N < 0) or np.any(actions_1N >= self.n_actions):
            raise ValueError(f"actions: expected values in 0..{self.n_actions - 1}, got {actions}")
        result = self.world.step(actions_1N)
        obs = self._per_agent(result.next_obs_BND[0])
        rewards = {a: float(r) for a, r in self._per_agent(result.rewards_BN[0]).items()}
        terminated = dict.fromkeys(self.agents, bool(result.terminated_B[0]))
        truncated = dict.fromkeys(self.agents, bool(result.truncated_B[0]))
        infos = self._infos()
        if result.terminated_B[0] or result.truncated_B[0]:
            self.agents = []
        return obs, rewards, terminated, truncated, infos

    def close(self) -> None:
        pass
