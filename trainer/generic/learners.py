"""`GenericTrainer`: the `trainer.domain.EnvTrainer` of an environment that brings numbers
(`GenericTraining`) instead of a trainer: Algorithm 1's loop (`trainer.loop`) on the generic
rollouts, gated by the generic gates."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from policy.qnet import StackedQNet
from trainer.domain import EnvTrainer, TrainedBatch
from trainer.generic.config import GenericImpactConfig, GenericTaskConfig, GenericTraining
from trainer.generic.gates import impact_gates, task_gates
from trainer.generic.rollouts import ImpactRollout, TaskRollout
from trainer.loop import ProgressFn, train_soft_q

GATE_SEED_OFFSET = 10_007  # gates never see the training worlds' seeds


class GenericTrainer(EnvTrainer):
    """The generic learners of environment `env` with its numbers `training`."""

    no_joint_reason = (
        "the generic trainer has no joint-learner baseline (an environment that wants one "
        "registers a trainer of its own: docs/extending.md)"
    )

    def __init__(self, env: str, training: GenericTraining) -> None:
        self.env, self.training = env, training
        self.production_parents_only = training.production_parents_only

    def default_configs(self) -> tuple[GenericTaskConfig, GenericImpactConfig]:
        return (
            replace(self.training.task, env=self.env),
            replace(self.training.impact, env=self.env),
        )

    def train_tasks(
        self,
        goals: Sequence[str],
        config: GenericTaskConfig,
        *,
        seed: int,
        progress: ProgressFn | None,
        evaluate: bool,
    ) -> TrainedBatch:
        rollout = TaskRollout(self.env, goals, config, seed)
        learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
        gates = (
            task_gates(learner.online, self.env, goals, config, seed + GATE_SEED_OFFSET)
            if evaluate
            else []
        )
        members: list[tuple[str, ...]] = [(g,) for g in goals]
        return TrainedBatch(
            "task", members, learner.online, learner.spec, config, seed, curves, gates
        )

    def train_impacts(
        self,
        partner_goals: Sequence[str],
        partner_task_nets: StackedQNet,
        config: GenericImpactConfig,
        *,
        seed: int,
        progress: ProgressFn | None,
        evaluate: bool,
    ) -> TrainedBatch:
        rollout = ImpactRollout(self.env, partner_goals, partner_task_nets, config, seed)
        learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
        gates = (
            impact_gates(
                learner.online,
                partner_task_nets,
                self.env,
                partner_goals,
                config,
                seed + GATE_SEED_OFFSET,
            )
            if evaluate
            else []
        )
        members: list[tuple[str, ...]] = [(g,) for g in partner_goals]
        return TrainedBatch(
            "impact", members, learner.online, learner.spec, config, seed, curves, gates
        )

    def print_gates(self, batches: Sequence[TrainedBatch], console: Any = None) -> None:
        """Nothing: the summary table shows every number of the generic gates."""
