"""The three learners of the paper, each training a batch of networks at once.

- `train_tasks`: one task network per goal (eqs. 3-5);
- `train_impacts`: one impact network per partner goal, by self-play against the frozen task
  network of that goal (eqs. 6-7);
- `train_joint`: the joint-learner baseline, one network per goal combination.

Each returns a `TrainedBatch`: the stacked networks, their training curves and their gate results.
Given a cooking configuration (`trainer.cooking_config`), `train_tasks` and `train_impacts` train
in the kitchen instead (`trainer.cooking_learners`): the configuration names the world, so the
zoo and the job backends need no environment-specific code.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from envs.particle.goals import GOAL_IDS, goal_index
from policy.qnet import QNetSpec, StackedQNet
from trainer.config import ImpactConfig, JointConfig, SoftQConfig, TaskConfig
from trainer.cooking_config import CookingImpactConfig, CookingTaskConfig
from trainer.cooking_gates import CookingImpactGate, CookingTaskGate
from trainer.gates import ImpactGate, TaskGate, impact_gates, task_gates
from trainer.loop import ProgressFn, TrainingCurves, train_soft_q
from trainer.particle_rollouts import (
    ParticleImpactRollout,
    ParticleJointRollout,
    ParticleTaskRollout,
)

Kind = Literal["task", "impact", "joint"]
GateResults = (
    list[TaskGate] | list[ImpactGate] | list[CookingTaskGate] | list[CookingImpactGate] | list[None]
)


@dataclass
class TrainedBatch:
    """G networks trained together; member g belongs to `goals[g]` (a combination for joint)."""

    kind: Kind
    goals: list[tuple[str, ...]]
    nets: StackedQNet
    spec: QNetSpec
    config: SoftQConfig
    seed: int
    curves: TrainingCurves
    gates: GateResults = field(default_factory=list)

    def gate_passed(self, g: int) -> bool | None:
        gate = self.gates[g] if self.gates else None
        return None if gate is None else gate.passed

    def curve_summary(self, g: int) -> dict[str, Any]:
        """Start, best and final mean episode return of member g (the full curve goes to plots)."""
        series = [row[g] for row in self.curves.returns_G]
        if not series:
            return {}
        return {
            "first": series[0],
            "best": max(series),
            "final": series[-1],
            "points": len(series),
            "steps": self.curves.steps[-1],
        }

    def curve_series(self, g: int) -> dict[str, list[int] | list[float]]:
        """Member g's whole training curve (registered with its version, drawn by the web
        console): the training step of each point, the mean return of the episodes that ended
        since the point before, and the mean loss of the updates since then."""
        return {
            "steps": list(self.curves.steps),
            "mean_return": [row[g] for row in self.curves.returns_G],
            "loss": [row[g] for row in self.curves.losses_G],
        }


def _indices(goals: Sequence[str]) -> list[int]:
    return [goal_index(g) for g in goals]


def train_tasks(
    goals: Sequence[str],
    config: TaskConfig | CookingTaskConfig,
    *,
    seed: int,
    progress: ProgressFn | None = None,
    evaluate: bool = True,
) -> TrainedBatch:
    """Task networks for `goals`, trained side by side in one batched world."""
    if isinstance(config, CookingTaskConfig):
        from trainer.cooking_learners import train_cooking_tasks

        return train_cooking_tasks(goals, config, seed=seed, progress=progress, evaluate=evaluate)
    idx = _indices(goals)
    rollout = ParticleTaskRollout(idx, config, seed)
    learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
    gates = task_gates(learner.online, idx, config, seed + 10_007) if evaluate else []
    return TrainedBatch(
        "task", [(g,) for g in goals], learner.online, learner.spec, config, seed, curves, gates
    )


def train_impacts(
    partner_goals: Sequence[str],
    partner_task_nets: StackedQNet,
    config: ImpactConfig | CookingImpactConfig,
    *,
    seed: int,
    progress: ProgressFn | None = None,
    evaluate: bool = True,
) -> TrainedBatch:
    """Impact networks for `partner_goals`; member g of `partner_task_nets` is goal g's task net."""
    if isinstance(config, CookingImpactConfig):
        from trainer.cooking_learners import train_cooking_impacts

        return train_cooking_impacts(
            partner_goals, partner_task_nets, config, seed=seed, progress=progress,
            evaluate=evaluate,
        )  # fmt: skip
    idx = _indices(partner_goals)
    rollout = ParticleImpactRollout(idx, partner_task_nets, config, seed)
    learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
    gates = (
        impact_gates(learner.online, partner_task_nets, idx, config, seed + 10_007)
        if evaluate
        else []
    )
    return TrainedBatch(
        "impact",
        [(g,) for g in partner_goals],
        learner.online,
        learner.spec,
        config,
        seed,
        curves,
        gates,
    )


def train_joint(
    combos: Sequence[Sequence[str]],
    partner_task_nets: Sequence[StackedQNet],
    config: JointConfig,
    *,
    seed: int,
    progress: ProgressFn | None = None,
) -> TrainedBatch:
    """JL networks, one per (ego goal, partner goals...) combination, on the team reward.

    `partner_task_nets[k]` stacks, for every combination, the task net of its k-th partner."""
    combos_idx = [_indices(c) for c in combos]
    rollout = ParticleJointRollout(combos_idx, partner_task_nets, config, seed)
    learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
    return TrainedBatch(
        "joint", [tuple(c) for c in combos], learner.online, learner.spec, config, seed, curves
    )


def all_goals() -> list[str]:
    return list(GOAL_IDS)


def chunked(items: Sequence[Any], size: int) -> list[list[Any]]:
    """Split `items` into batches of at most `size` (the last may be smaller)."""
    if size < 1:
        raise ValueError(f"batch size must be >= 1, got {size}")
    return [list(items[i : i + size]) for i in range(0, len(items), size)]
