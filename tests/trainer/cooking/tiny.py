"""Kitchen training settings small enough for a test: a few updates of one-layer networks, on
two kitchens and short episodes (the networks test the plumbing, not the cooking). Shared by the
trainer's and the evaluation's kitchen tests; `replace(CookingTaskConfig(), **TINY_COOKING)`."""

from __future__ import annotations

from typing import Any

TINY_COOKING: dict[str, Any] = dict(
    total_steps=20,
    warmup_steps=5,
    envs_per_net=2,
    batch_size=16,
    hidden=(16,),
    replay_size=500,
    pool_episodes=2,
    pool_steps=5,
    episode_steps=20,
)
# the same, gated on a few short evaluation episodes
TINY_COOKING_GATED: dict[str, Any] = {**TINY_COOKING, "eval_episodes": 2, "eval_steps": 10}
