"""The numbers of coexist's generic trainer for this world: a crossing takes ~10 steps."""

from trainer.generic import GenericImpactConfig, GenericTaskConfig, GenericTraining

SHARED: dict = {
    "hidden": (64, 64),
    "lr": 1e-3,
    "gamma": 0.9,
    "alpha": 0.05,
    "envs_per_net": 8,
    "warmup_steps": 50,
    "target_every": 100,
    "episode_steps": 50,
    "eval_episodes": 32,
    "eval_steps": 50,
}

TRAINING = GenericTraining(
    task=GenericTaskConfig(total_steps=3_000, success_threshold=0.6, **SHARED),
    impact=GenericImpactConfig(total_steps=2_000, **SHARED),
)
