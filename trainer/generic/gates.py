"""The generic quality gates: is a network of the generic machinery good enough to be served?

Both run `eval_episodes` episodes per network of at most `eval_steps` steps from seeded starts,
twice on the same seeds (common random numbers): once with the network, once with a uniformly
random ego in its place.

- Task gate (goal g; partner: a random goal, uniformly random actions): the network's mean
  return must exceed the random ego's by more than `return_margin`, and, where
  `success_threshold` > 0 and the domain can tell (`Domain.goal_reached`), the share of episodes
  in which the ego reaches its goal at some step must be at least `success_threshold`.
- Impact gate (partner goal h; the partner acts with h's task network): the partner's mean
  return beside the network must exceed its mean return beside the random ego by more than
  `partner_gain`.

Networks act by sampling their Boltzmann policy at the training α (what the server returns).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np
import torch

from envs.registry import get_domain
from policy.qnet import StackedQNet
from trainer.frozen import FrozenTaskNets
from trainer.generic.config import GenericImpactConfig, GenericTaskConfig
from trainer.generic.worlds import PairWorlds, goal_column

# (obs_B2D, rng) -> actions (B, 2)
PairPolicy = Callable[[np.ndarray, np.random.Generator], np.ndarray]


@dataclass(frozen=True)
class GenericTaskGate:
    goal: str
    success_rate: float  # nan: not judged
    mean_return: float
    random_ego_return: float
    passed: bool
    FAILURE_NOTE: ClassVar[str] = ""

    def metrics(self) -> dict[str, Any]:
        return asdict(self)

    def summary_cells(self) -> list[str]:
        success = "n/a" if np.isnan(self.success_rate) else f"{self.success_rate:.0%}"
        return [success, f"{self.mean_return:.2f}", f"{self.random_ego_return:.2f} (random ego)"]


@dataclass(frozen=True)
class GenericImpactGate:
    goal: str
    partner_return: float
    partner_return_random_ego: float
    passed: bool
    FAILURE_NOTE: ClassVar[str] = ""

    def metrics(self) -> dict[str, Any]:
        return asdict(self)

    def summary_cells(self) -> list[str]:
        return [
            "helps" if self.passed else "does not help",
            f"{self.partner_return:.2f} (partner)",
            f"{self.partner_return_random_ego:.2f} (random ego)",
        ]


def run_episodes(
    env: str,
    ego_goals: Sequence[str],
    partner_goals: Sequence[str],
    policy: PairPolicy,
    *,
    steps: int,
    seed: int,
) -> tuple[np.ndarray, np.ndarray]:
    """One episode per env (goals of env b: `ego_goals[b]`, `partner_goals[b]`) from seeded
    starts: both agents' returns (B, 2) and whether the ego reached its goal at some step (B,)
    (nan where the domain cannot tell)."""
    domain = get_domain(env)
    worlds = PairWorlds(env, ego_goals, partner_goals, episode_steps=steps + 1, seed=seed)
    rng = np.random.default_rng(seed)
    returns_B2 = np.zeros((worlds.n_envs, 2))
    reached_B = np.zeros(worlds.n_envs)
    running_B = np.ones(worlds.n_envs, dtype=bool)
    for _ in range(steps):
        rewards_B2, next_B2D, done_B = worlds.step(policy(worlds.obs_B2D, rng))
        returns_B2 += np.where(running_B[:, None], rewards_B2, 0.0)
        for b in map(int, np.flatnonzero(running_B)):
            hit = domain.goal_reached(next_B2D[b, 0][None], 2, ego_goals[b])
            reached_B[b] = np.nan if hit is None else max(reached_B[b], float(hit[0]))
        running_B &= ~done_B
        if not running_B.any():
            break
    return returns_B2, reached_B


def _sampled(nets: StackedQNet, views_BD: np.ndarray, n_nets: int, alpha: float, seed: int):
    frozen = FrozenTaskNets(nets, alpha, torch.Generator().manual_seed(seed))
    return frozen.act(views_BD.reshape(n_nets, -1, views_BD.shape[-1])).reshape(-1)


def task_gates(
    nets: StackedQNet, env: str, goals: Sequence[str], config: GenericTaskConfig, seed: int
) -> list[GenericTaskGate]:
    """The task gate of G networks (member g learned goals[g]); module docstring."""
    domain, n_nets, n_eps = get_domain(env), len(goals), config.eval_episodes
    ego_goals = goal_column(goals, n_eps)
    draw = np.random.default_rng(seed)
    partner_goals = [domain.goals[i] for i in draw.integers(0, len(domain.goals), len(ego_goals))]

    def with_ego(learned: bool) -> PairPolicy:
        def policy(obs_B2D: np.ndarray, rng: np.random.Generator) -> np.ndarray:
            n = len(obs_B2D)
            partner = rng.integers(0, domain.n_actions, n)
            ego = rng.integers(0, domain.n_actions, n)  # drawn in both runs: the same partner
            if learned:
                views = domain.task_views(obs_B2D[:, 0], 2)[:, 0].astype(np.float32)
                ego = _sampled(nets, views, n_nets, config.alpha, int(rng.integers(2**31)))
            return np.stack([ego, partner], axis=1)

        return policy

    steps = config.eval_steps
    learned, reached = run_episodes(
        env, ego_goals, partner_goals, with_ego(True), steps=steps, seed=seed
    )
    random, _ = run_episodes(env, ego_goals, partner_goals, with_ego(False), steps=steps, seed=seed)
    gates = []
    for g, goal in enumerate(goals):
        part = slice(g * n_eps, (g + 1) * n_eps)
        mean, baseline = float(learned[part, 0].mean()), float(random[part, 0].mean())
        success = float(np.mean(reached[part]))
        judged = config.success_threshold > 0 and not np.isnan(success)
        passed = mean > baseline + config.return_margin and (
            not judged or success >= config.success_threshold
        )
        gates.append(GenericTaskGate(goal, success, mean, baseline, bool(passed)))
    return gates


def impact_gates(
    impact_nets: StackedQNet,
    partner_task_nets: StackedQNet,
    env: str,
    partner_goals: Sequence[str],
    config: GenericImpactConfig,
    seed: int,
) -> list[GenericImpactGate]:
    """The impact gate of G networks (member g learned partner goal partner_goals[g])."""
    domain, n_nets, n_eps = get_domain(env), len(partner_goals), config.eval_episodes
    column = goal_column(partner_goals, n_eps)

    def with_ego(learned: bool) -> PairPolicy:
        def policy(obs_B2D: np.ndarray, rng: np.random.Generator) -> np.ndarray:
            n = len(obs_B2D)
            partner_views = domain.task_views(obs_B2D[:, 1], 2)[:, 0].astype(np.float32)
            partner = _sampled(
                partner_task_nets, partner_views, n_nets, config.alpha, int(rng.integers(2**31))
            )
            ego = rng.integers(0, domain.n_actions, n)
            if learned:
                views = domain.task_views(obs_B2D[:, 0], 2)[:, 0].astype(np.float32)
                ego = _sampled(impact_nets, views, n_nets, config.alpha, int(rng.integers(2**31)))
            return np.stack([ego, partner], axis=1)

        return policy

    steps = config.eval_steps
    helped, _ = run_episodes(env, column, column, with_ego(True), steps=steps, seed=seed)
    random, _ = run_episodes(env, column, column, with_ego(False), steps=steps, seed=seed)
    gates = []
    for g, goal in enumerate(partner_goals):
        part = slice(g * n_eps, (g + 1) * n_eps)
        with_net, baseline = float(helped[part, 1].mean()), float(random[part, 1].mean())
        passed = with_net > baseline + config.partner_gain
        gates.append(GenericImpactGate(goal, with_net, baseline, bool(passed)))
    return gates
