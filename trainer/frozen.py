"""Frozen task networks that act and value the world beside a learner (paper §3.2, self-play).

The impact learner's partner acts with the frozen task network of its goal, and eq. 6 rewards
the learner with the change of that network's soft value; the joint baseline's partners act
the same way. Every environment's rollouts use this one class.
"""

from __future__ import annotations

import numpy as np
import torch

from policy.qnet import StackedQNet
from policy.torch_ops import sample_boltzmann_t, soft_value_t


class FrozenTaskNets:
    """G frozen task networks acting (Boltzmann at α, eq. 2) and valuing (eq. 3) their views."""

    def __init__(self, nets: StackedQNet, alpha: float, generator: torch.Generator) -> None:
        self.nets, self.alpha, self.generator = nets, alpha, generator

    @torch.no_grad()
    def q_values(self, views_GED: np.ndarray) -> torch.Tensor:
        """Q (G, E, A) of views (G, E, D); views (G, E, K, D) are K task views of one agent
        whose Q-values are averaged, as the inference engine serves an agent with K others."""
        views = torch.from_numpy(np.ascontiguousarray(views_GED, dtype=np.float32))
        if views.dim() == 3:
            return self.nets(views)
        n_nets, n_envs, n_views, dim = views.shape
        q = self.nets(views.reshape(n_nets, n_envs * n_views, dim))
        return q.reshape(n_nets, n_envs, n_views, -1).mean(dim=2)

    def act(self, views_GED: np.ndarray) -> np.ndarray:
        """Actions (G, E)."""
        return sample_boltzmann_t(self.q_values(views_GED), self.alpha, self.generator).numpy()

    def soft_value(self, views_GED: np.ndarray) -> np.ndarray:
        """V (G, E), eq. 3."""
        return soft_value_t(self.q_values(views_GED), self.alpha).numpy()
