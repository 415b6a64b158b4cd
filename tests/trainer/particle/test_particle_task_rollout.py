"""The task learner's other agent: a share of training episodes has it resting on a wall."""

from __future__ import annotations

import numpy as np
import pytest

from envs.particle.goals import goal_index
from trainer.config import TaskConfig
from trainer.particle.rollouts import ParticleTaskRollout, wall_states


def test_wall_states_lie_on_a_wall_at_rest_and_include_corners() -> None:
    states_N4 = wall_states(np.random.default_rng(0), 3000)
    xy_N2 = states_N4[:, :2]
    on_wall_N2 = (xy_N2 == 0.0) | (xy_N2 == 1.0)
    assert on_wall_N2.any(axis=1).all() and (states_N4[:, 2:] == 0.0).all()
    corners = on_wall_N2.all(axis=1).mean()
    assert 0.25 < corners < 0.45  # a third of them, plus the rare exact ends of a side
    assert ((xy_N2 >= 0.0) & (xy_N2 <= 1.0)).all()


def test_a_resting_partner_stays_on_its_wall_for_the_episode() -> None:
    config = TaskConfig(envs_per_net=64, partner_wall_prob=0.5)
    rollout = ParticleTaskRollout([goal_index("d3")], config, seed=3)
    resting_B = rollout.resting_B.copy()
    assert 0.2 < resting_B.mean() < 0.8
    start_xy = rollout.world.state[resting_B, 1, :2]
    for _ in range(20):
        rollout.step(np.zeros((1, 64), dtype=np.int64))
    np.testing.assert_allclose(rollout.world.state[resting_B, 1, :2], start_xy)
    assert not np.allclose(rollout.world.state[~resting_B, 1, :2], 0.0)


def test_shares_outside_zero_to_one_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="partner_wall_prob: expected a share in"):
        TaskConfig(partner_wall_prob=1.5)
    with pytest.raises(ValueError, match="wall_success_threshold: expected a share in"):
        TaskConfig(wall_success_threshold=-0.1)
