"""What the learner sees and earns in the generic machinery (paper §3.1-3.2), as Algorithm 1's
`trainer.loop.Rollout`s over `PairWorlds`.

| learner | learner's view | reward | the partner |
|---|---|---|---|
| task (goal g) | task view (ego, partner): `task_views(obs_ego)[:, 0]` | the ego's own reward | a random goal, uniformly random actions |
| impact (partner goal h) | the same pair (the impact view) | I = V^h(s') − V^h(s) on the partner view, eq. 6 | acts with the frozen task net of h on its own task view |
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from envs.registry import get_domain
from policy.qnet import StackedQNet
from trainer.frozen import FrozenTaskNets
from trainer.generic.config import GenericImpactConfig, GenericTaskConfig
from trainer.generic.worlds import PairWorlds, goal_column
from trainer.loop import EpisodeTracker


class _PairRollout:
    """What both learners share: G networks x E envs, the pair views, the returns."""

    def __init__(self, env: str, n_nets: int, envs_per_net: int) -> None:
        self.domain = get_domain(env)
        self.n_nets, self.envs_per_net = n_nets, envs_per_net
        self.obs_dim = self.domain.pair_obs_dim
        self.n_actions = self.domain.n_actions
        self.tracker = EpisodeTracker(n_nets, envs_per_net)

    def grouped(self, rows_BD: np.ndarray) -> np.ndarray:
        return rows_BD.reshape(self.n_nets, self.envs_per_net, -1).astype(np.float32)

    def pair_views(self, obs_BD: np.ndarray) -> np.ndarray:
        """(ego, other) views of B observations of the same side, (G, E, pair_obs_dim)."""
        return self.grouped(self.domain.task_views(obs_BD, 2)[:, 0])

    def finished_returns(self) -> list[list[float]]:
        return self.tracker.pop()


class TaskRollout(_PairRollout):
    """Ego (agent 0) learns goal g; the partner has a random goal and acts at random."""

    def __init__(self, env: str, goals: Sequence[str], config: GenericTaskConfig, seed: int):
        super().__init__(env, len(goals), config.envs_per_net)
        self.rng = np.random.default_rng(seed + 1)
        self.worlds = PairWorlds(
            env,
            goal_column(goals, config.envs_per_net),
            None,
            episode_steps=config.episode_steps,
            seed=seed,
        )

    def observe(self) -> np.ndarray:
        return self.pair_views(self.worlds.obs_B2D[:, 0])

    def step(self, actions_GE: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        partner_B = self.rng.integers(0, self.n_actions, self.worlds.n_envs)
        rewards_B2, next_B2D, done_B = self.worlds.step(
            np.stack([actions_GE.reshape(-1), partner_B], axis=1)
        )
        self.tracker.add(rewards_B2[:, 0], done_B)
        reward_GE = rewards_B2[:, 0].reshape(self.n_nets, self.envs_per_net)
        return reward_GE.astype(np.float32), self.pair_views(next_B2D[:, 0])


class ImpactRollout(_PairRollout):
    """Ego (agent 0) learns the impact on a partner of goal h that acts with h's task network."""

    def __init__(
        self,
        env: str,
        partner_goals: Sequence[str],
        partner_task_nets: StackedQNet,
        config: GenericImpactConfig,
        seed: int,
    ) -> None:
        super().__init__(env, len(partner_goals), config.envs_per_net)
        column = goal_column(partner_goals, config.envs_per_net)
        # The ego has no task of its own here; its goal only fills the slot (reward unused).
        self.worlds = PairWorlds(env, column, column, episode_steps=config.episode_steps, seed=seed)
        generator = torch.Generator().manual_seed(seed + 1)
        self.partners = FrozenTaskNets(partner_task_nets, config.alpha, generator)

    def observe(self) -> np.ndarray:
        return self.pair_views(self.worlds.obs_B2D[:, 0])

    def partner_views(self, obs_BD: np.ndarray) -> np.ndarray:
        return self.grouped(self.domain.partner_view(obs_BD, 2, 1))

    def step(self, actions_GE: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        obs_B2D = self.worlds.obs_B2D
        partner_GE = self.partners.act(self.pair_views(obs_B2D[:, 1]))
        before_GED = self.partner_views(obs_B2D[:, 0])
        _, next_B2D, done_B = self.worlds.step(
            np.stack([actions_GE.reshape(-1), partner_GE.reshape(-1)], axis=1)
        )
        # Eq. 6: the impact is the change of the partner's soft value, on the partner's view.
        after_GED = self.partner_views(next_B2D[:, 0])
        impact_GE = self.partners.soft_value(after_GED) - self.partners.soft_value(before_GED)
        self.tracker.add(impact_GE.reshape(-1), done_B)
        return impact_GE.astype(np.float32), self.pair_views(next_B2D[:, 0])
