"""B particle worlds stepped at once, for training and evaluation (no PettingZoo overhead).

Dynamics, reward and observations are the pure functions of `envs.particle.world`; this class only
keeps the state, the step counters and a seeded generator for start states.

| array          | shape       | dtype   | meaning                                                |
|----------------|-------------|---------|--------------------------------------------------------|
| `goals_BN`     | (B, N)      | int     | goal index (into `GOAL_IDS`) of every agent            |
| `state`        | (B, N, 4)   | float64 | [x, y, vx, vy] of every agent                          |
| `obs_BND`      | (B, N, 4N)  | float32 | every agent's observation (own block first)            |
| `rewards_BN`   | (B, N)      | float64 | reward of the transition, computed on the next state   |
| `terminated_B` | (B,)        | bool    | every agent inside its target area after this step     |
| `truncated_B`  | (B,)        | bool    | step counter reached `max_steps`, not terminated       |

`step` never resets: `next_obs_BND` is the true next observation, so the trainer can store the
transition before calling `reset_where(terminated_B | truncated_B)`. Stepping a finished world
simply continues it. Everything is deterministic given `seed`.
"""

from __future__ import annotations

import numpy as np

from envs.batched import BatchedWorlds, StepResult
from envs.particle.goals import N_GOALS
from envs.particle.world import (
    STATE_DIM,
    in_target,
    observations,
    random_states,
    rewards,
    step_state,
)

MAX_AGENTS = 5


def _as_goals(goals_BN: np.ndarray) -> np.ndarray:
    goals_BN = np.asarray(goals_BN)
    if goals_BN.ndim != 2 or goals_BN.shape[0] < 1 or not 1 <= goals_BN.shape[1] <= MAX_AGENTS:
        raise ValueError(f"goals_BN: expected shape (B >= 1, N in 1..5), got {goals_BN.shape}")
    if not np.issubdtype(goals_BN.dtype, np.integer):
        raise ValueError(f"goals_BN: expected goal indices (integers), got dtype {goals_BN.dtype}")
    if goals_BN.min() < 0 or goals_BN.max() >= N_GOALS:
        raise ValueError(f"goals_BN: expected goal indices in 0..{N_GOALS - 1}")
    return goals_BN.astype(np.int64)


class BatchedParticleWorld(BatchedWorlds):
    """B independent worlds of N agents each; see the module docstring for shapes."""

    def __init__(
        self, goals_BN: np.ndarray, *, max_steps: int = 1000, seed: int | None = None
    ) -> None:
        if max_steps < 1:
            raise ValueError(f"max_steps: expected >= 1, got {max_steps}")
        self._goals_BN = _as_goals(goals_BN)
        self.max_steps = max_steps
        self._rng = np.random.default_rng(seed)
        self._state_BN4 = random_states(self._rng, self.n_envs, self.n_agents)
        self._steps_B = np.zeros(self.n_envs, dtype=np.int64)
        self._last_obs_BND = self.observe()

    @property
    def goals(self) -> np.ndarray:
        """Goal indices, shape (B, N) (a copy)."""
        return self._goals_BN.copy()

    @property
    def state(self) -> np.ndarray:
        """Current state, shape (B, N, 4) (a copy)."""
        return self._state_BN4.copy()

    @property
    def steps(self) -> np.ndarray:
        """Steps taken since each world's last reset, shape (B,) (a copy)."""
        return self._steps_B.copy()

    def set_goals(self, goals_BN: np.ndarray) -> None:
        """Replace the goals (same B and N); the states and step counters are kept."""
        goals_BN = _as_goals(goals_BN)
        if goals_BN.shape != self._goals_BN.shape:
            expected = self._goals_BN.shape
            raise ValueError(f"goals_BN: expected shape {expected}, got {goals_BN.shape}")
        self._goals_BN = goals_BN

    def observe(self) -> np.ndarray:
        """Every agent's observation of the current state, shape (B, N, 4N), float32."""
        self._last_obs_BND = observations(self._state_BN4).astype(np.float32)
        return self._last_obs_BND.copy()

    def reset(self, states_BN4: np.ndarray | None = None) -> np.ndarray:
        """Start every world afresh: from `states_BN4` if given, else from random start states."""
        if states_BN4 is None:
            self._state_BN4 = random_states(self._rng, self.n_envs, self.n_agents)
        else:
            states_BN4 = np.asarray(states_BN4, dtype=np.float64)
            expected = (self.n_envs, self.n_agents, STATE_DIM)
            if states_BN4.shape != expected:
                raise ValueError(f"states_BN4: expected shape {expected}, got {states_BN4.shape}")
            if not np.all(np.isfinite(states_BN4)):
                raise ValueError("states_BN4: expected finite values")
            self._state_BN4 = states_BN4.copy()
        self._steps_B[:] = 0
        return self.observe()

    def _restart(self, mask_B: np.ndarray, n_reset: int) -> None:
        """Re-sample the start states of the masked worlds (`reset_where`)."""
        self._state_BN4[mask_B] = random_states(self._rng, n_reset, self.n_agents)
        self._steps_B[mask_B] = 0

    def place(self, mask_B: np.ndarray, agent: int, states_M4: np.ndarray) -> np.ndarray:
        """Put `agent` of the masked worlds in the states `states_M4` (one row per masked world,
        in order); their step counters and the other agents are kept. The observations after."""
        mask_B = np.asarray(mask_B, dtype=bool)
        states_M4 = np.asarray(states_M4, dtype=np.float64)
        if states_M4.shape != (int(mask_B.sum()), STATE_DIM):
            raise ValueError(f"states_M4: expected shape ({int(mask_B.sum())}, {STATE_DIM})")
        self._state_BN4[mask_B, agent] = states_M4
        return self.observe()

    def step(self, actions_BN: np.ndarray) -> StepResult:
        """Advance every world one step with the actions of every agent, shape (B, N)."""
        self._state_BN4 = step_state(self._state_BN4, actions_BN)
        self._steps_B += 1
        rewards_BN = rewards(self._state_BN4, self._goals_BN)
        terminated_B = np.all(in_target(self._state_BN4, self._goals_BN), axis=-1)
        truncated_B = (self._steps_B >= self.max_steps) & ~terminated_B
        return StepResult(self.observe(), rewards_BN, terminated_B, truncated_B)
