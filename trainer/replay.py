"""A replay buffer for G networks trained side by side: one ring buffer per network, stored stacked.

Every network gets its own transitions (its own goal's rollouts) and its own minibatch; storing
them as (G, capacity, ...) tensors lets one `gather` sample all G minibatches at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class Batch:
    """One minibatch per network: obs_GBD, act_GB, rew_GB, next_obs_GBD, and where the
    environment can end an episode, ended_GB (1.0 where the transition ended it: no bootstrap)."""

    obs_GBD: torch.Tensor
    act_GB: torch.Tensor
    rew_GB: torch.Tensor
    next_obs_GBD: torch.Tensor
    ended_GB: torch.Tensor | None = None


class StackedReplay:
    """G ring buffers of `capacity` transitions each, filled in lock-step; with `endings`, each
    transition also records whether it ended its episode (an environment's termination, not a
    time limit)."""

    def __init__(self, n_nets: int, capacity: int, obs_dim: int, *, endings: bool = False) -> None:
        if n_nets < 1 or capacity < 1 or obs_dim < 1:
            raise ValueError(
                f"StackedReplay: n_nets, capacity, obs_dim must be >= 1, got {n_nets}, {capacity}, {obs_dim}"
            )
        self.capacity = capacity
        self.obs_GCD = torch.zeros(n_nets, capacity, obs_dim)
        self.next_obs_GCD = torch.zeros(n_nets, capacity, obs_dim)
        self.act_GC = torch.zeros(n_nets, capacity, dtype=torch.long)
        self.rew_GC = torch.zeros(n_nets, capacity)
        self.ended_GC = torch.zeros(n_nets, capacity) if endings else None
        self.cursor = 0
        self.size = 0

    def add(
        self,
        obs_GED: torch.Tensor,
        act_GE: torch.Tensor,
        rew_GE: torch.Tensor,
        next_obs_GED: torch.Tensor,
        ended_GE: torch.Tensor | None = None,
    ) -> None:
        """Append E transitions to each of the G buffers (overwriting the oldest when full);
        `ended_GE` is required exactly when the buffer records endings."""
        if (ended_GE is None) != (self.ended_GC is None):
            raise ValueError("StackedReplay.add: ended_GE is required exactly with endings=True")
        n_new = obs_GED.shape[1]
        idx = (self.cursor + torch.arange(n_new)) % self.capacity
        self.obs_GCD[:, idx] = obs_GED
        self.next_obs_GCD[:, idx] = next_obs_GED
        self.act_GC[:, idx] = act_GE
        self.rew_GC[:, idx] = rew_GE
        if self.ended_GC is not None and ended_GE is not None:
            self.ended_GC[:, idx] = ended_GE.to(self.ended_GC.dtype)
        self.cursor = (self.cursor + n_new) % self.capacity
        self.size = min(self.size + n_new, self.capacity)

    def sample(self, batch_size: int, generator: torch.Generator) -> Batch:
        """Uniform minibatch of `batch_size` per network (independent indices per network)."""
        if self.size == 0:
            raise ValueError("StackedReplay.sample: the buffer is empty")
        n_nets = self.rew_GC.shape[0]
        idx_GB = torch.randint(0, self.size, (n_nets, batch_size), generator=generator)
        obs_dim = self.obs_GCD.shape[2]
        idx_GBD = idx_GB.unsqueeze(-1).expand(-1, -1, obs_dim)
        return Batch(
            obs_GBD=torch.gather(self.obs_GCD, 1, idx_GBD),
            act_GB=torch.gather(self.act_GC, 1, idx_GB),
            rew_GB=torch.gather(self.rew_GC, 1, idx_GB),
            next_obs_GBD=torch.gather(self.next_obs_GCD, 1, idx_GBD),
            ended_GB=None if self.ended_GC is None else torch.gather(self.ended_GC, 1, idx_GB),
        )
