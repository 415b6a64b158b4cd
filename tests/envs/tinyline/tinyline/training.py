"""The corridor's numbers for coexist's generic trainer: short episodes, few steps."""

from trainer.generic import GenericImpactConfig, GenericTaskConfig, GenericTraining

TRAINING = GenericTraining(
    task=GenericTaskConfig(
        hidden=(32, 32),
        lr=1e-3,
        gamma=0.9,
        alpha=0.05,
        envs_per_net=8,
        warmup_steps=20,
        target_every=50,
        episode_steps=20,
        total_steps=1_500,
        eval_episodes=32,
        eval_steps=20,
        success_threshold=0.4,
    ),
    impact=GenericImpactConfig(
        hidden=(32, 32),
        lr=1e-3,
        gamma=0.9,
        alpha=0.05,
        envs_per_net=8,
        warmup_steps=20,
        target_every=50,
        episode_steps=20,
        total_steps=1_000,
        eval_episodes=32,
        eval_steps=20,
    ),
)
