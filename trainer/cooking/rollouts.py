"""What the learning cook sees and earns in the kitchen, for the task and impact learners.

Both rollouts run G networks, each in E copies of its recipe's training kitchen
(`trainer.cooking.kitchens`: layout, seats, the scripted other cook, restarts).

| learner                 | learner's seat | learner's view             | reward                               |
|-------------------------|----------------|----------------------------|--------------------------------------|
| task (recipe g)         | focal          | task view (ego, other)     | its own reward, shaped by sub-goals  |
| impact (partner goal h) | the other seat | impact view (ego, partner) | I = V^h(s'_p) - V^h(s_p) (eq. 6), by |
|                         |                |                            | default plus the partner's reward r_p|
|                         |                |                            | (`CookingImpactConfig.impact_reward`)|

In the impact rollout the focal cook is the *partner*: it acts with the frozen task network of h
(Boltzmann at α) on its own view (self-play); the learner's world recipe is the kitchen's other
recipe, never rewarded. The partner's r_p is the shaped reward its V was trained on. Curves record
unshaped returns (+20 dish, -0.01 per waiting step) for task networks and the impact sum for
impact networks (the partner's unshaped returns are kept in `partner_returns`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from envs.cooking import COOKING
from policy.qnet import StackedQNet
from trainer.cooking.config import CookingConfig, CookingImpactConfig
from trainer.cooking.kitchens import Kitchens
from trainer.frozen import FrozenTaskNets


class _Returns:
    """Running unshaped returns per kitchen; finished episodes grouped by network."""

    def __init__(self, n_nets: int, envs_per_net: int) -> None:
        self.running_GE = np.zeros((n_nets, envs_per_net))
        self.finished: list[list[float]] = [[] for _ in range(n_nets)]

    def add(self, g: int, reward_E: np.ndarray, done_E: np.ndarray) -> None:
        self.running_GE[g] += reward_E
        self.finished[g].extend(self.running_GE[g, done_E].tolist())
        self.running_GE[g, done_E] = 0.0

    def pop(self) -> list[list[float]]:
        out, self.finished = self.finished, [[] for _ in self.finished]
        return out


class CookingTaskRollout:
    """The learner cooks recipe g at its kitchen's focal seat; the other cook is scripted."""

    obs_dim = COOKING.pair_obs_dim
    n_actions = COOKING.n_actions

    def __init__(self, recipes: Sequence[str], config: CookingConfig, seed: int) -> None:
        self.n_nets, self.envs_per_net = len(recipes), config.envs_per_net
        self.config = config
        self.kitchens = [
            Kitchens(r, config.envs_per_net, config, seed + 7919 * g) for g, r in enumerate(recipes)
        ]
        self.returns = _Returns(self.n_nets, self.envs_per_net)

    def observe(self) -> np.ndarray:
        return np.stack([k.views(k.focal) for k in self.kitchens]).astype(np.float32)

    def step(self, actions_GE: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rewards, next_views = [], []
        for g, k in enumerate(self.kitchens):
            actions_BN = np.zeros((self.envs_per_net, 2), dtype=np.int64)
            actions_BN[:, k.focal] = actions_GE[g]
            actions_BN[:, k.other] = k.scripted_other(self.config.partner_random_prob)
            out = k.step(actions_BN)
            rewards.append(out.rewards_BN[:, k.focal])
            next_views.append(COOKING.task_views(out.next_obs_BND[:, k.focal], 2)[:, 0])
            self.returns.add(g, out.unshaped_BN[:, k.focal], out.done_B)
        return np.stack(rewards).astype(np.float32), np.stack(next_views).astype(np.float32)

    def finished_returns(self) -> list[list[float]]:
        return self.returns.pop()


class CookingImpactRollout:
    """The learner sits beside a partner cooking h with h's frozen task network (self-play)."""

    obs_dim = COOKING.pair_obs_dim
    n_actions = COOKING.n_actions

    def __init__(
        self,
        partner_recipes: Sequence[str],
        partner_task_nets: StackedQNet,
        config: CookingImpactConfig,
        seed: int,
    ) -> None:
        self.n_nets, self.envs_per_net = len(partner_recipes), config.envs_per_net
        self.config = config
        self.kitchens = [
            Kitchens(r, config.envs_per_net, config, seed + 7919 * g)
            for g, r in enumerate(partner_recipes)
        ]
        generator = torch.Generator().manual_seed(seed + 1)
        self.partners = FrozenTaskNets(partner_task_nets, config.alpha, generator)
        self.returns = _Returns(self.n_nets, self.envs_per_net)
        self.partner_returns = _Returns(self.n_nets, self.envs_per_net)

    def _views(self, obs_per_net: Sequence[np.ndarray], partner: bool) -> np.ndarray:
        """Impact views (ego, partner) or partner views (partner, ego) from the ego's obs."""
        view = COOKING.partner_view if partner else COOKING.impact_view
        return np.stack([view(obs, 2, 1) for obs in obs_per_net]).astype(np.float32)

    def _ego_obs(self, obs_BND_per_net: Sequence[np.ndarray]) -> list[np.ndarray]:
        return [obs[:, k.other] for obs, k in zip(obs_BND_per_net, self.kitchens, strict=True)]

    def observe(self) -> np.ndarray:
        return self._views(self._ego_obs([k.obs_BND for k in self.kitchens]), partner=False)

    def step(self, actions_GE: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        partner_view_GED = self._views(self._ego_obs([k.obs_BND for k in self.kitchens]), True)
        partner_act_GE = self.partners.act(partner_view_GED)
        outs = []
        for g, k in enumerate(self.kitchens):
            actions_BN = np.zeros((self.envs_per_net, 2), dtype=np.int64)
            actions_BN[:, k.other], actions_BN[:, k.focal] = actions_GE[g], partner_act_GE[g]
            outs.append(k.step(actions_BN))
        next_ego_obs = self._ego_obs([o.next_obs_BND for o in outs])
        next_partner_view_GED = self._views(next_ego_obs, partner=True)
        # Eq. 6: the change of the partner's soft value, on the partner's view of the state.
        impact_GE = self.partners.soft_value(next_partner_view_GED) - self.partners.soft_value(
            partner_view_GED
        )
        partner_rewards_GE = np.stack(
            [o.rewards_BN[:, k.focal] for o, k in zip(outs, self.kitchens, strict=True)]
        )
        if self.config.impact_reward == "value_change_plus_reward":
            impact_GE = impact_GE + partner_rewards_GE  # the partner's reward the V was trained on
        for g, (o, k) in enumerate(zip(outs, self.kitchens, strict=True)):
            self.returns.add(g, impact_GE[g], o.done_B)
            self.partner_returns.add(g, o.unshaped_BN[:, k.focal], o.done_B)
        return impact_GE.astype(np.float32), self._views(next_ego_obs, partner=False)

    def finished_returns(self) -> list[list[float]]:
        return self.returns.pop()
