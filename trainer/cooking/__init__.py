"""The trainer's kitchen: kitchens, shaping, rollouts, gates and learners
(`trainer.domain.EnvTrainer`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from policy.qnet import StackedQNet
from trainer.cooking import config
from trainer.cooking.config import CookingImpactConfig, CookingTaskConfig
from trainer.cooking.gates import print_cooking_gates
from trainer.cooking.learners import train_cooking_impacts, train_cooking_tasks
from trainer.domain import EnvTrainer
from trainer.learners import TrainedBatch
from trainer.loop import ProgressFn


class CookingTrainer(EnvTrainer):
    """`trainer.domain.EnvTrainer` of the kitchen (no joint-learner baseline: `train_joint` is
    the protocol's refusal)."""

    # An impact network learned beside a task network that cannot cook learns to help a partner
    # that fails anyway (the first cooking zoo did: parent `latest`, a 75 % CarrotBanana network).
    production_parents_only = True
    no_joint_reason = "the joint-learner baseline is trained for the particle world only"

    def default_configs(self) -> tuple[CookingTaskConfig, CookingImpactConfig]:
        return config.CookingTaskConfig(), config.CookingImpactConfig()

    def train_tasks(
        self,
        goals: Sequence[str],
        config: CookingTaskConfig,
        *,
        seed: int,
        progress: ProgressFn | None,
        evaluate: bool,
    ) -> TrainedBatch:
        return train_cooking_tasks(goals, config, seed=seed, progress=progress, evaluate=evaluate)

    def train_impacts(
        self,
        partner_goals: Sequence[str],
        partner_task_nets: StackedQNet,
        config: CookingImpactConfig,
        *,
        seed: int,
        progress: ProgressFn | None,
        evaluate: bool,
    ) -> TrainedBatch:
        return train_cooking_impacts(
            partner_goals,
            partner_task_nets,
            config,
            seed=seed,
            progress=progress,
            evaluate=evaluate,
        )

    def print_gates(self, batches: Sequence[TrainedBatch], console: Any = None) -> None:
        print_cooking_gates(batches, console)


TRAINER = CookingTrainer()
