"""The soft-Q training loop of Algorithm 1, shared by the task, impact and joint learners.

What differs between the learners is only *what the learning agent sees and is rewarded with*,
so that lives in a `Rollout` (task.py, impact.py, joint.py); this loop owns acting, replay,
updates and target copies, for G networks at once.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, cast

import numpy as np
import torch

from policy.qnet import QNetSpec
from trainer.config import SoftQConfig
from trainer.replay import StackedReplay
from trainer.soft_q import StackedSoftQ


class Rollout(Protocol):
    """Batched environments for G networks with E environments each."""

    n_nets: int
    envs_per_net: int
    obs_dim: int
    n_actions: int

    def observe(self) -> np.ndarray:
        """The learners' current views, (G, E, D) float32."""
        ...

    def step(self, actions_GE: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Apply the learners' actions; returns (reward_GE, next_view_GED) of this transition.

        Episodes that end are restarted inside the rollout (after the transition is returned);
        their returns are handed out by `finished_returns`."""
        ...

    def finished_returns(self) -> list[list[float]]:
        """Returns of the episodes finished since the last call, one list per network."""
        ...


class EndingRollout(Rollout, Protocol):
    """A rollout whose environment ends episodes (beside the time limit): the learner must not
    bootstrap past an ending (eq. 5 with r alone)."""

    def ended(self) -> np.ndarray:
        """(G, E) bool: which transitions of the last `step` ended their episode."""
        ...


class EpisodeTracker:
    """Per-env returns of G networks with E envs each (env b belongs to network b // E); hands
    out the finished episodes grouped by network (a `Rollout`'s `finished_returns`)."""

    def __init__(self, n_nets: int, envs_per_net: int) -> None:
        self.n_nets, self.envs_per_net = n_nets, envs_per_net
        self.running_B = np.zeros(n_nets * envs_per_net)
        self.finished: list[list[float]] = [[] for _ in range(n_nets)]

    def add(self, reward_B: np.ndarray, done_B: np.ndarray) -> None:
        self.running_B += reward_B
        for b in np.flatnonzero(done_B):
            self.finished[b // self.envs_per_net].append(float(self.running_B[b]))
        self.running_B[done_B] = 0.0

    def pop(self) -> list[list[float]]:
        out, self.finished = self.finished, [[] for _ in range(self.n_nets)]
        return out


@dataclass
class TrainingCurves:
    """Mean episode return per network, sampled along training (paper Fig. 4)."""

    steps: list[int] = field(default_factory=list)
    returns_G: list[list[float]] = field(default_factory=list)
    losses_G: list[list[float]] = field(default_factory=list)


ProgressFn = Callable[[int, int], None]
"""`progress(done, total)`: called after every batched training step."""
ProgressFactory = Callable[[str, int], ProgressFn]
"""`factory(description, total_steps)` -> the progress callback of one batch of goals."""


def train_soft_q(
    rollout: Rollout,
    config: SoftQConfig,
    *,
    seed: int,
    progress: ProgressFn | None = None,
    log_every: int = 100,
) -> tuple[StackedSoftQ, TrainingCurves]:
    """Train G soft-Q networks on `rollout` for `config.total_steps` batched steps.

    Runs on `COEXIST_TORCH_THREADS` torch threads (default 1): the stacked networks already keep
    a core busy, and a second thread competing with the simulator, a server or another training
    process made updates up to twentyfold slower on 2 cores (benchmarks/training.py)."""
    torch.set_num_threads(int(os.environ.get("COEXIST_TORCH_THREADS", "1")))
    torch.manual_seed(seed)
    generator = torch.Generator().manual_seed(seed)
    spec = QNetSpec(
        obs_dim=rollout.obs_dim, n_actions=rollout.n_actions, hidden=tuple(config.hidden)
    )
    learner = StackedSoftQ(
        spec,
        rollout.n_nets,
        lr=config.lr,
        gamma=config.gamma,
        alpha=config.alpha,
        generator=generator,
    )
    endings = callable(getattr(rollout, "ended", None))  # an `EndingRollout`
    replay = StackedReplay(rollout.n_nets, config.replay_size, rollout.obs_dim, endings=endings)
    curves = TrainingCurves()
    pending: list[list[float]] = [[] for _ in range(rollout.n_nets)]
    losses = torch.zeros(rollout.n_nets)
    n_loss = 0

    view_GED = torch.from_numpy(rollout.observe())
    for step in range(config.total_steps):
        act_GE = learner.act(view_GED, explore_eps=config.explore_eps)
        rew_GE, next_GED = rollout.step(act_GE.numpy())
        ended_GE = torch.from_numpy(cast(EndingRollout, rollout).ended()) if endings else None
        replay.add(view_GED, act_GE, torch.from_numpy(rew_GE), torch.from_numpy(next_GED), ended_GE)
        view_GED = torch.from_numpy(rollout.observe())

        if step >= config.warmup_steps:
            for _ in range(config.updates_per_step):
                stats = learner.update(replay.sample(config.batch_size, generator))
                losses += stats.loss_G
                n_loss += 1
                if learner.n_updates % config.target_every == 0:
                    learner.sync_target()

        for g, finished in enumerate(rollout.finished_returns()):
            pending[g].extend(finished)
        at_log_point = (step + 1) % log_every == 0 or step + 1 == config.total_steps
        if at_log_point and all(pending):
            curves.steps.append(step + 1)
            curves.returns_G.append([float(np.mean(p)) for p in pending])
            curves.losses_G.append((losses / max(n_loss, 1)).tolist())
            pending = [[] for _ in range(rollout.n_nets)]
            losses.zero_()
            n_loss = 0
        if progress is not None:
            progress(step + 1, config.total_steps)
    return learner, curves
