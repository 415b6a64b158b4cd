"""Which trainer an environment's registration names (`envs.registry.EnvPlugin.training`):
its own `trainer.domain.EnvTrainer`, or the generic machinery (`trainer.generic`) with its
numbers (the rules: `trainer.domain`'s docstring)."""

from __future__ import annotations

from functools import cache

from envs.registry import env_plugin, load_reference
from trainer.domain import EnvTrainer
from trainer.generic import GenericTrainer, GenericTraining

_TRAINER_METHODS = ("default_configs", "train_tasks", "train_impacts", "train_joint", "print_gates")


@cache
def env_trainer(env: str) -> EnvTrainer:
    """The trainer of environment `env` (module docstring); ValueError for an unknown env or a
    registration whose `training` is neither."""
    training = env_plugin(env).training  # a clear ValueError naming the known environments
    what = f"env {env!r}: training"
    if isinstance(training, str):
        training = load_reference(training, what)
    if training is None:
        training = GenericTraining()
    if isinstance(training, GenericTraining):
        return GenericTrainer(env, training)
    missing = [m for m in _TRAINER_METHODS if not callable(getattr(training, m, None))]
    if missing:
        raise ValueError(
            f"{what}: expected a trainer.generic.GenericTraining or a trainer.domain.EnvTrainer, "
            f"got {type(training).__name__} (without {', '.join(missing)})"
        )
    trainer: EnvTrainer = training  # type: ignore[assignment]  # checked member by member
    return trainer
