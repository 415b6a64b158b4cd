"""States and labels for the particle world's goal monitors (`trainer.monitor`).

States: where the answer of "which actions keep the target" changes, at and around the target
area, and some anywhere. An agent is drawn uniformly in its goal's target area widened by
`MARGIN` on each side (clipped to the world), `NEAR_SHARE` of the time, else anywhere; its speed
up to the cap in a random direction, `REST_SHARE` of them at rest and `AXIS_SHARE` of the moving
ones along one axis only (an agent that has only pushed up and down for a while has no sideways
speed left: the blend's help often moves it so, along its target's edge); the partner anywhere,
moving at most half the cap per axis (it does not enter the monitored agent's answer:
`goal_kept` reads the agent alone).

Labels (`monitor_labels`): `goal_kept` in the target area shrunk by `LABEL_MARGIN` on each side
that is not a wall.
Why: a network is smooth and the true answer jumps at the area's edge, so the monitor errs in a
band around whichever edge it learns. Learnt on the exact area, that band straddles the edge:
measured, an ego resting 0.003 outside its target with no sideways speed was told three of its
five actions keep the target, and the blend walked it up and down the edge, outside, for the
rest of the episode. Learnt on the shrunk area, the band lies inside the true one, where every
answer is safe; the cost is the `LABEL_MARGIN` strip along the edge, where the ego acts as SL
does. The gate still judges the monitor against the exact `goal_kept`."""

from __future__ import annotations

import numpy as np

from envs.particle.domain import box_kept
from envs.particle.goals import TARGET_BOXES_G4, goal_index
from envs.particle.world import MAX_SPEED

MARGIN = 0.15  # three full-speed steps outside the target area
NEAR_SHARE = 0.8
REST_SHARE = 0.3
AXIS_SHARE = 0.2
LABEL_MARGIN = 0.02  # the labels' target area: the true one less this on each side


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
    one_axis = rng.random(n) < AXIS_SHARE  # the other axis's component set to 0
    velocity[one_axis, rng.integers(0, 2, int(one_axis.sum()))] = 0.0
    partner_xy = rng.uniform(0.0, 1.0, (n, 2))
    partner_v = rng.uniform(-MAX_SPEED / 2, MAX_SPEED / 2, (n, 2))
    return np.concatenate([xy, velocity, partner_xy, partner_v], axis=1)


def monitor_labels(obs: np.ndarray, goal: str) -> np.ndarray:
    """(n, A) bool: the labels a monitor of `goal` learns on observations `obs` (n, 8), the
    monitored agent first: `goal_kept` in its target area less `LABEL_MARGIN` on each side
    but a side on the world's edge (a wall, which no agent crosses)."""
    box = TARGET_BOXES_G4[goal_index(goal)]
    inward = np.array([1.0, -1.0, 1.0, -1.0])
    on_wall = (box == 0.0) | (box == 1.0)
    return box_kept(obs[:, :4], np.where(on_wall, box, box + LABEL_MARGIN * inward))
