"""Soft Q-learning for G networks at once (paper eqs. 2-5, Algorithm 1).

The G networks are independent (one per goal) but their weights are stacked, so one batched
matmul evaluates all of them and one Adam step updates all of them. Adam is element-wise, so a
stacked Adam is exactly G separate Adams; the loss is the *sum* of the G per-network losses, so
each network receives exactly its own gradient.

The gradient of eq. 4 is written out by hand (`_backward`) instead of taken by autograd: the
loss reads one Q-value per sample, so the output layer's gradient is a scatter of the TD errors,
and each hidden layer costs two batched matmuls (weights, inputs) and one ReLU mask. Autograd
took the same matmuls plus a transposed copy of every activation, a bias expansion and its graph
bookkeeping, which at these sizes (G x 128 samples x 128 units) cost as much as the matmuls.
`tests/trainer/test_trainer_soft_q.py` checks the hand-written gradient against autograd's.
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
    rew_GB: torch.Tensor, next_q_GBA: torch.Tensor, gamma: float, alpha: float
) -> torch.Tensor:
    """Eq. 5: r + γ V_target(s'), with V from eq. 3. No terminal mask: episodes only time out."""
    return rew_GB + gamma * soft_value_t(next_q_GBA, alpha)


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

    @torch.no_grad()
    def set_gradients(self, batch: Batch) -> UpdateStats:
        """Set every online parameter's `.grad` to the gradient of Σ_g J_Q(θ_g) (eq. 4) on
        `batch`, without stepping; returns the per-network loss and mean predicted Q."""
        target_GB = soft_q_target(
            batch.rew_GB, self.target(batch.next_obs_GBD), self.gamma, self.alpha
        )
        acts = _forward_keep(self.online, batch.obs_GBD)
        act_GB1 = batch.act_GB.unsqueeze(-1)
        q_GB = acts[-1].gather(2, act_GB1).squeeze(-1)
        err_GB = q_GB - target_GB
        loss_G = 0.5 * err_GB.square().mean(dim=1)  # eq. 4, per network
        # dJ/dQ(s, a): (Q - target) / B at the action taken, zero at the others
        dq_GBA = torch.zeros_like(acts[-1])
        dq_GBA.scatter_(2, act_GB1, (err_GB / err_GB.shape[1]).unsqueeze(-1))
        _backward(self.online, acts, dq_GBA)
        return UpdateStats(loss_G=loss_G, q_mean_G=q_GB.mean(dim=1))

    def sync_target(self) -> None:
        """Hard copy θ̄ ← θ (Algorithm 1)."""
        self.target.load_state_dict(self.online.state_dict())


def _forward_keep(net: StackedQNet, x_GBD: torch.Tensor) -> list[torch.Tensor]:
    """The stacked forward of `net`, keeping every layer's input: [x, h_1, ..., h_K, q].

    x_GBD: (G, B, obs_dim); h_k: (G, B, hidden[k-1]) after the activation; q: (G, B, A)."""
    if net.spec.activation != "relu":
        raise ValueError(
            f"activation: the hand-written update supports relu, got {net.spec.activation!r}"
        )
    acts = [x_GBD.to(net.spec.torch_dtype)]
    last = len(net.weights) - 1
    for k, (w, b) in enumerate(zip(net.weights, net.biases, strict=True)):
        h = torch.baddbmm(b.unsqueeze(1), acts[-1], w.transpose(1, 2))
        if k < last:
            h.relu_()
        acts.append(h)
    return acts


def _backward(net: StackedQNet, acts: list[torch.Tensor], grad_GBO: torch.Tensor) -> None:
    """Set `.grad` of every weight and bias of `net` from dJ/d(output), layer by layer.

    For layer k with input h (G, B, in) and output gradient d (G, B, out): dW = dᵀ h
    (G, out, in), db = Σ_B d, and the input's gradient d W masked where h = relu(.) was 0."""
    for k in range(len(net.weights) - 1, -1, -1):
        w, b, h_in = net.weights[k], net.biases[k], acts[k]
        if w.shape[1] <= w.shape[2]:  # dW = dᵀ h, (G, out, in)
            w.grad = torch.bmm(grad_GBO.transpose(1, 2), h_in)
        else:  # the same as (hᵀ d)ᵀ: BLAS is several times faster with the wide side last
            w.grad = torch.bmm(h_in.transpose(1, 2), grad_GBO).transpose(1, 2).contiguous()
        b.grad = grad_GBO.sum(dim=1)
        if k > 0:
            # relu's gradient in one fused pass (a boolean mask and masked_fill took 10x longer)
            grad_GBO = torch.ops.aten.threshold_backward(torch.bmm(grad_GBO, w), h_in, 0.0)
