"""B PettingZoo envs of one registered environment, two agents each, stepped side by side.

The generic machinery knows an environment only through its registration: `make_env` and the
`Domain`. Agent 0 of each env (its first `possible_agents` entry) is the learner, agent 1 its
partner. An env's episode ends when it terminates or truncates for either agent, or after
`episode_steps`; training bootstraps through both (the shared loop has no terminal mask, as for
coexist's own worlds: `trainer.cooking.config`), and the env restarts with a fresh seed.

Shapes: `obs_B2D` is B envs' two observations of D features.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from envs.registry import get_domain, make_env


class PairWorlds:
    """B envs of `env`; env b's agents pursue `ego_goals[b]` and `partner_goals[b]` (a partner
    goal drawn uniformly from the catalogue at every restart where `partner_goals` is None)."""

    def __init__(
        self,
        env: str,
        ego_goals: Sequence[str],
        partner_goals: Sequence[str] | None,
        *,
        episode_steps: int,
        seed: int,
    ) -> None:
        self.name, self.domain = env, get_domain(env)
        self.rng = np.random.default_rng(seed)
        self.episode_steps = episode_steps
        self.ego_goals = list(ego_goals)
        self.redraw = partner_goals is None
        self.partner_goals = list(partner_goals) if partner_goals is not None else list(ego_goals)
        n_envs = len(self.ego_goals)
        self.envs: list[Any] = [None] * n_envs
        self.obs_B2D = np.zeros((n_envs, 2, self.domain.obs_dim(2)), dtype=np.float32)
        self.t_B = np.zeros(n_envs, dtype=np.int64)
        for b in range(n_envs):
            self._start(b)

    @property
    def n_envs(self) -> int:
        return len(self.envs)

    def _start(self, b: int) -> None:
        goals = self.domain.goals
        if self.redraw:
            self.partner_goals[b] = goals[int(self.rng.integers(len(goals)))]
        env = make_env(
            self.name, (self.ego_goals[b], self.partner_goals[b]), max_steps=self.episode_steps
        )
        observations, _ = env.reset(seed=int(self.rng.integers(2**31)))
        self.envs[b] = env
        self.obs_B2D[b] = stacked(env, observations, self.obs_B2D[b])
        self.t_B[b] = 0

    def step(self, actions_B2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Both agents' actions (B, 2) -> their rewards (B, 2), the observations they lead to
        (B, 2, D) and which episodes ended (B,) bool; ended envs restart (`obs_B2D` is then the
        fresh start's)."""
        rewards_B2 = np.zeros((self.n_envs, 2), dtype=np.float64)
        next_B2D = self.obs_B2D.copy()
        done_B = np.zeros(self.n_envs, dtype=bool)
        for b, env in enumerate(self.envs):
            agents = env.possible_agents[:2]
            actions = {a: int(actions_B2[b, i]) for i, a in enumerate(agents) if a in env.agents}
            observations, rewards, terminated, truncated, _ = env.step(actions)
            rewards_B2[b] = [float(rewards.get(a, 0.0)) for a in agents]
            next_B2D[b] = stacked(env, observations, self.obs_B2D[b])
            self.t_B[b] += 1
            done_B[b] = (
                self.t_B[b] >= self.episode_steps
                or any(terminated.get(a, True) or truncated.get(a, True) for a in agents)
                or not env.agents
            )
        self.obs_B2D = next_B2D.copy()
        for ended in np.flatnonzero(done_B):
            self._start(int(ended))
        return rewards_B2, next_B2D, done_B


def stacked(env: Any, observations: dict[str, Any], last_2D: np.ndarray) -> np.ndarray:
    """The first two agents' observations as (2, D) float32; an agent that has left the env
    keeps its last observation."""
    rows = [
        np.asarray(observations[a], dtype=np.float32).reshape(-1)
        if a in observations
        else last_2D[i]
        for i, a in enumerate(env.possible_agents[:2])
    ]
    return np.stack(rows)


def goal_column(goals: Sequence[str], repeat: int) -> list[str]:
    """Each goal `repeat` times in a row: the goals of G networks' E envs each."""
    return [g for g in goals for _ in range(repeat)]
