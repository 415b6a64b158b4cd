"""What every domain's batched simulator shares: B independent worlds of N agents, each agent
with one goal index, stepped together (the trainer's vectorised rollouts; a PettingZoo env is
the same simulator with B = 1, `envs.parallel`).

Shapes carry suffixes: `goals_BN` is B worlds of N agents' goal indices.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class StepResult(NamedTuple):
    """One step of B worlds: every agent's next observation (B, N, D), reward (B, N), and per
    world whether its episode ended (terminated: the goals; truncated: the step limit), (B,)."""

    next_obs_BND: np.ndarray
    rewards_BN: np.ndarray
    terminated_B: np.ndarray
    truncated_B: np.ndarray


class BatchedWorlds:
    """The sizes of a batch of worlds, read from its goal indices `_goals_BN` (B, N), and the
    restart of some of them (`reset_where`: the trainer restarts each world as it ends)."""

    _goals_BN: np.ndarray
    _last_obs_BND: np.ndarray  # the observations `observe` returned last

    @property
    def n_envs(self) -> int:
        return int(self._goals_BN.shape[0])

    @property
    def n_agents(self) -> int:
        return int(self._goals_BN.shape[1])

    def observe(self) -> np.ndarray:
        """Every agent's observation of the current state, (B, N, D) float32 (a copy)."""
        raise NotImplementedError

    def _restart(self, mask_B: np.ndarray, n_reset: int) -> None:
        """Put the `n_reset` worlds of `mask_B` in fresh start states, step counters at 0."""
        raise NotImplementedError

    def reset_where(self, mask_B: np.ndarray) -> np.ndarray:
        """Restart the masked worlds (B,) bool and zero their step counters; the observations
        after."""
        mask_B = np.asarray(mask_B, dtype=bool)
        if mask_B.shape != (self.n_envs,):
            raise ValueError(f"mask_B: expected shape ({self.n_envs},), got {mask_B.shape}")
        n_reset = int(mask_B.sum())
        if n_reset == 0:
            return self._last_obs_BND.copy()  # nothing changed since the last step
        self._restart(mask_B, n_reset)
        return self.observe()
