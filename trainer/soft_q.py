"""Soft Q-learning for G networks at once (paper eqs. 2-5, Algorithm 1).

The G networks are independent (one per goal) but their weights are stacked, so one batched
matmul evaluates all of them and one Adam step updates all of them. Adam is element-wise, so a
stacked Adam is exactly G separate Adams; the loss is the *sum* of the G per-network losses, so
each network receives exactly its own gradient.

The gradient of eq. 4 is autograd's through `StackedQNet.forward`;
`tests/trainer/test_trainer_soft_q.py` checks it, member by member, against one `QNetwork`'s.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import torch

from policy.qnet import QNetSpec, StackedQNet
from policy.torch_ops import sample_boltzmann_t, soft_value_t
from trainer.replay import Batch


@dataclass(frozen=True)
class UpdateStats:
    """Per-network results of one update: loss_G (eq. 4) and mean predicted Q."""

    loss_G: torch.Tensor
    q_mean_G: torch.Tensor


def soft_q_target(
    rew_GB: torch.Tensor,
    next_q_GBA: torch.Tensor,
    gamma: float,
    alpha: float,
    ended_GB: torch.Tensor | None = None,
) -> torch.Tensor:
    """Eq. 5: r + γ V_target(s'), with V from eq. 3; r alone where the transition ended its
    episode (`ended_GB` 1.0: the environment's termination). A time limit is not an ending: the
    state it cuts off still has its value."""
    if ended_GB is None:
        return rew_GB + gamma * soft_value_t(next_q_GBA, alpha)
    return rew_GB + gamma * (1.0 - ended_GB) * soft_value_t(next_q_GBA, alpha)


class StackedSoftQ:
    """Online and target stacks of G Q-networks, Boltzmann acting and soft-Q updates."""

    def __init__(
        self,
        spec: QNetSpec,
        n_nets: int,
        *,
        lr: float,
        gamma: float,
        alpha: float,
        generator: torch.Generator,
    ) -> None:
        self.spec = spec
        self.gamma = gamma
        self.alpha = alpha
        self.online = StackedQNet(spec, n_nets, generator=generator)
        self.target = copy.deepcopy(self.online)
        self.target.requires_grad_(False)
        # fused: one kernel per tensor for the whole Adam step (the same update as the reference
        # loop over element-wise ops, without a dozen passes over G x 128 x 128 weights)
        self.optimizer = torch.optim.Adam(self.online.parameters(), lr=lr, fused=True)
        self.generator = generator
        self.n_updates = 0

    @torch.no_grad()
    def act(self, obs_GED: torch.Tensor, explore_eps: float = 0.0) -> torch.Tensor:
        """One action per env: Boltzmann at temperature α (eq. 2), replaced by a uniformly
        random action with probability `explore_eps` (the behaviour policy may differ from the
        learned one: the soft-Q target of eq. 5 does not depend on the action taken next)."""
        actions = sample_boltzmann_t(self.online(obs_GED), self.alpha, self.generator)
        if explore_eps <= 0.0:
            return actions
        n_actions = self.spec.n_actions
        uniform = torch.randint(0, n_actions, actions.shape, generator=self.generator)
        explore = torch.rand(actions.shape, generator=self.generator) < explore_eps
        return torch.where(explore, uniform, actions)

    def update(self, batch: Batch) -> UpdateStats:
        """One gradient step on J_Q (eq. 4) for all G networks."""
        stats = self.set_gradients(batch)
        self.optimizer.step()
        self.n_updates += 1
        return stats

    def set_gradients(self, batch: Batch) -> UpdateStats:
        """Set every online parameter's `.grad` to the gradient of Σ_g J_Q(θ_g) (eq. 4) on
        `batch`, without stepping; returns the per-network loss and mean predicted Q."""
        with torch.no_grad():
            next_q_GBA = self.target(batch.next_obs_GBD)
            target_GB = soft_q_target(
                batch.rew_GB, next_q_GBA, self.gamma, self.alpha, batch.ended_GB
            )
        q_GB = self.online(batch.obs_GBD).gather(2, batch.act_GB.unsqueeze(-1)).squeeze(-1)
        loss_G = 0.5 * (q_GB - target_GB).square().mean(dim=1)  # eq. 4, per network
        self.optimizer.zero_grad(set_to_none=True)
        loss_G.sum().backward()  # a sum: each network's gradient is its own loss's alone
        return UpdateStats(loss_G=loss_G.detach(), q_mean_G=q_GB.detach().mean(dim=1))

    def sync_target(self) -> None:
        """Hard copy θ̄ ← θ (Algorithm 1)."""
        self.target.load_state_dict(self.online.state_dict())
