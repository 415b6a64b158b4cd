"""The paper's three learners in the particle world (§3.1-3.2, §4.1-4.2).

The soft-Q loop (`trainer.loop`, Algorithm 1) on the particle rollouts
(`trainer.particle.rollouts`), gated by `trainer.particle.gates`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from envs.particle.goals import goal_index
from policy.qnet import StackedQNet
from trainer.config import ImpactConfig, JointConfig, TaskConfig
from trainer.learners import TrainedBatch
from trainer.loop import ProgressFn, train_soft_q
from trainer.particle.gates import impact_gates, joint_gates, task_gates
from trainer.particle.monitor_states import monitor_labels, monitor_states
from trainer.particle.rollouts import (
    ParticleImpactRollout,
    ParticleJointRollout,
    ParticleTaskRollout,
)

GATE_SEED_OFFSET = 10_007  # gates never see the training worlds' seeds


def _indices(goals: Sequence[str]) -> list[int]:
    return [goal_index(g) for g in goals]


class ParticleTrainer:
    """`trainer.domain.EnvTrainer` of the particle world."""

    no_joint_reason = ""
    production_parents_only = False  # quick tiny zoos (`--fast`, tests) serve failed networks
    monitor_states = staticmethod(monitor_states)  # goal monitors' states (`trainer.monitor`)
    monitor_labels = staticmethod(monitor_labels)  # and what they learn

    def default_configs(self) -> tuple[TaskConfig, ImpactConfig]:
        return TaskConfig(), ImpactConfig()

    def train_tasks(
        self,
        goals: Sequence[str],
        config: TaskConfig,
        *,
        seed: int,
        progress: ProgressFn | None,
        evaluate: bool,
    ) -> TrainedBatch:
        idx = _indices(goals)
        rollout = ParticleTaskRollout(idx, config, seed)
        learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
        gates = task_gates(learner.online, idx, config, seed + GATE_SEED_OFFSET) if evaluate else []
        members: list[tuple[str, ...]] = [(g,) for g in goals]
        return TrainedBatch(
            "task", members, learner.online, learner.spec, config, seed, curves, gates
        )

    def train_impacts(
        self,
        partner_goals: Sequence[str],
        partner_task_nets: StackedQNet,
        config: ImpactConfig,
        *,
        seed: int,
        progress: ProgressFn | None,
        evaluate: bool,
    ) -> TrainedBatch:
        idx = _indices(partner_goals)
        rollout = ParticleImpactRollout(idx, partner_task_nets, config, seed)
        learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
        gates = (
            impact_gates(learner.online, partner_task_nets, idx, config, seed + GATE_SEED_OFFSET)
            if evaluate
            else []
        )
        members: list[tuple[str, ...]] = [(g,) for g in partner_goals]
        return TrainedBatch(
            "impact", members, learner.online, learner.spec, config, seed, curves, gates
        )

    def train_joint(
        self,
        combos: Sequence[Sequence[str]],
        partner_task_nets: Sequence[StackedQNet],
        config: JointConfig,
        *,
        seed: int,
        progress: ProgressFn | None,
        ego_task_nets: StackedQNet | None = None,
    ) -> TrainedBatch:
        indices = [_indices(c) for c in combos]
        rollout = ParticleJointRollout(indices, partner_task_nets, config, seed)
        learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
        gates = (
            joint_gates(
                learner.online,
                indices,
                ego_task_nets,
                partner_task_nets,
                config,
                seed + GATE_SEED_OFFSET,
            )
            if ego_task_nets is not None
            else []
        )
        members: list[tuple[str, ...]] = [tuple(c) for c in combos]
        return TrainedBatch(
            "joint", members, learner.online, learner.spec, config, seed, curves, gates
        )

    def print_gates(self, batches: Sequence[TrainedBatch], console: Any = None) -> None:
        """Nothing: the summary table shows every number of the particle gates."""
