"""The task and impact learners of the paper in the kitchen (§3.1-3.2, §4.3).

The same soft-Q loop (`trainer.loop`, Algorithm 1) as in the particle world, on the cooking
rollouts (`trainer.cooking.rollouts`) and gated by `trainer.cooking.gates`; the kitchen's
`trainer.domain.EnvTrainer` (`trainer.cooking.TRAINER`) calls them.
"""

from __future__ import annotations

from collections.abc import Sequence

from envs.cooking.recipes import recipe_index
from policy.qnet import StackedQNet
from trainer.cooking.config import CookingImpactConfig, CookingTaskConfig
from trainer.cooking.gates import cooking_impact_gates, cooking_task_gates
from trainer.cooking.rollouts import CookingImpactRollout, CookingTaskRollout
from trainer.learners import TrainedBatch
from trainer.loop import ProgressFn, train_soft_q

GATE_SEED_OFFSET = 10_007  # gates never see the training kitchens' seeds


def _checked(recipes: Sequence[str]) -> list[str]:
    for r in recipes:
        recipe_index(r, "goals")
    return list(recipes)


def train_cooking_tasks(
    recipes: Sequence[str],
    config: CookingTaskConfig,
    *,
    seed: int,
    progress: ProgressFn | None = None,
    evaluate: bool = True,
) -> TrainedBatch:
    """One task network per recipe, each in its training kitchen, trained side by side."""
    recipes = _checked(recipes)
    rollout = CookingTaskRollout(recipes, config, seed)
    learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
    gates = (
        cooking_task_gates(learner.online, recipes, config, seed + GATE_SEED_OFFSET)
        if evaluate
        else []
    )
    goals: list[tuple[str, ...]] = [(r,) for r in recipes]
    return TrainedBatch("task", goals, learner.online, learner.spec, config, seed, curves, gates)


def train_cooking_impacts(
    partner_recipes: Sequence[str],
    partner_task_nets: StackedQNet,
    config: CookingImpactConfig,
    *,
    seed: int,
    progress: ProgressFn | None = None,
    evaluate: bool = True,
) -> TrainedBatch:
    """One impact network per partner recipe, by self-play beside its frozen task network."""
    recipes = _checked(partner_recipes)
    rollout = CookingImpactRollout(recipes, partner_task_nets, config, seed)
    learner, curves = train_soft_q(rollout, config, seed=seed, progress=progress)
    gates = (
        cooking_impact_gates(
            learner.online, partner_task_nets, recipes, config, seed + GATE_SEED_OFFSET
        )
        if evaluate
        else []
    )
    goals: list[tuple[str, ...]] = [(r,) for r in recipes]
    return TrainedBatch("impact", goals, learner.online, learner.spec, config, seed, curves, gates)
