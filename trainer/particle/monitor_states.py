"""States for the particle world's goal monitors (`trainer.monitor`): where the answer of "which
actions keep the target" changes, at and around the target area, and some anywhere.

An agent is drawn uniformly in its goal's target area widened by `MARGIN` on each side (clipped
to the world), `NEAR_SHARE` of the time, else anywhere; its speed up to the cap in a random
direction, `REST_SHARE` of them at rest; the partner anywhere, moving at most half the cap per
axis (it does not enter the monitored agent's answer: `goal_kept` reads the agent alone)."""

from __future__ import annotations

import numpy as np

from envs.particle.goals import TARGET_BOXES_G4, goal_index
from envs.particle.world import MAX_SPEED

MARGIN = 0.15  # three full-speed steps outside the target area
NEAR_SHARE = 0.8
REST_SHARE = 0.3


def monitor_states(rng: np.random.Generator, goal: str, n: int) -> np.ndarray:
    """n observations (n, 8) of a two-agent scene, the monitored agent first."""
    box = TARGET_BOXES_G4[goal_index(goal)]
    low = np.array([box[0], box[2]]) - MARGIN
    high = np.array([box[1], box[3]]) + MARGIN
    near = rng.random(n) < NEAR_SHARE
    xy = np.where(near[:, None], rng.uniform(low, high, (n, 2)), rng.uniform(0.0, 1.0, (n, 2)))
    xy = np.clip(xy, 0.0, 1.0)
    speed = rng.uniform(0.0, MAX_SPEED, n) * (rng.random(n) >= REST_SHARE)
    angle = rng.uniform(0.0, 2 * np.pi, n)
    velocity = np.stack([np.cos(angle), np.sin(angle)], axis=1) * speed[:, None]
    partner_xy = rng.uniform(0.0, 1.0, (n, 2))
    partner_v = rng.uniform(-MAX_SPEED / 2, MAX_SPEED / 2, (n, 2))
    return np.concatenate([xy, velocity, partner_xy, partner_v], axis=1)
