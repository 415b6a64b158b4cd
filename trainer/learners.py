"""The three learners of the paper, each training a batch of networks at once.

- `train_tasks`: one task network per goal (eqs. 3-5);
- `train_impacts`: one impact network per partner goal, by self-play against the frozen task
  network of that goal (eqs. 6-7);
- `train_joint`: the joint-learner baseline, one network per goal combination.

Each returns a `TrainedBatch`: the stacked networks, their training curves and their gate results.
The configuration names its environment (`SoftQConfig.env_name()`) and that environment's trainer
(`trainer.plugins.env_trainer`: its own, or the generic machinery with its numbers) does the
training, so the zoo and the job backends need no environment-specific code.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from envs.registry import get_domain
from policy.qnet import StackedQNet
from trainer.config import SoftQConfig
from trainer.domain import TrainedBatch
from trainer.loop import ProgressFn
from trainer.plugins import env_trainer


def train_tasks(
    goals: Sequence[str],
    config: SoftQConfig,
    *,
    seed: int,
    progress: ProgressFn | None = None,
    evaluate: bool = True,
) -> TrainedBatch:
    """Task networks for `goals`, trained side by side in one batched world of `config.env_name()`."""
    return env_trainer(config.env_name()).train_tasks(
        goals, config, seed=seed, progress=progress, evaluate=evaluate
    )


def train_impacts(
    partner_goals: Sequence[str],
    partner_task_nets: StackedQNet,
    config: SoftQConfig,
    *,
    seed: int,
    progress: ProgressFn | None = None,
    evaluate: bool = True,
) -> TrainedBatch:
    """Impact networks for `partner_goals`; member g of `partner_task_nets` is goal g's task net."""
    return env_trainer(config.env_name()).train_impacts(
        partner_goals, partner_task_nets, config, seed=seed, progress=progress, evaluate=evaluate
    )


def train_joint(
    combos: Sequence[Sequence[str]],
    partner_task_nets: Sequence[StackedQNet],
    config: SoftQConfig,
    *,
    seed: int,
    progress: ProgressFn | None = None,
    ego_task_nets: StackedQNet | None = None,
) -> TrainedBatch:
    """JL networks, one per (ego goal, partner goals...) combination, on the team reward.

    `partner_task_nets[k]` stacks, for every combination, the task net of its k-th partner;
    with `ego_task_nets` (every combination's ego's task net) each network is gated against
    it (`trainer.particle.gates.joint_gates`), else it has no gate."""
    return env_trainer(config.env_name()).train_joint(
        combos,
        partner_task_nets,
        config,
        seed=seed,
        progress=progress,
        ego_task_nets=ego_task_nets,
    )


def all_goals(env: str = "particle") -> list[str]:
    """Every goal of `env`'s catalogue."""
    return list(get_domain(env).goals)


def chunked(items: Sequence[Any], size: int) -> list[list[Any]]:
    """Split `items` into batches of at most `size` (the last may be smaller)."""
    if size < 1:
        raise ValueError(f"batch size must be >= 1, got {size}")
    return [list(items[i : i + size]) for i in range(0, len(items), size)]


def combos_by_size(combos: Sequence[Sequence[str]]) -> list[tuple[int, list[tuple[str, ...]]]]:
    """Goal combinations grouped by their number of agents, fewest first: the joint networks of
    one size train together (one batch, one seed and run key per size)."""
    groups: dict[int, list[tuple[str, ...]]] = {}
    for combo in combos:
        groups.setdefault(len(combo), []).append(tuple(combo))
    return sorted(groups.items())
