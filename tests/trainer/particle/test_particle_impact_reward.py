"""The impact reward of eq. 6 against a hand-built two-agent case."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from envs.particle.goals import goal_index
from envs.particle.world import ACCELERATION, DAMPING, DT
from policy.qnet import QNetSpec, StackedQNet
from trainer.config import ImpactConfig
from trainer.particle.rollouts import ParticleImpactRollout


def _partner_net_valuing_ego_x() -> StackedQNet:
    """A 'task network' whose Q is the ego's x (input 4 of the partner's view) for every action.

    The partner's view is (partner block, ego block), so V^h(s) = x_ego + α log 5 (eq. 3) and the
    impact reward I = V^h(s') - V^h(s) is exactly the ego's displacement along x.
    """
    spec = QNetSpec(obs_dim=8, n_actions=5, hidden=(2,))
    net = StackedQNet(spec, 1)
    with torch.no_grad():
        net.weights[0].zero_()
        net.biases[0].zero_()
        net.weights[0][0, 0, 4] = 1.0  # hidden unit 0 = relu(x_ego) = x_ego
        net.weights[1].zero_()
        net.biases[1].zero_()
        net.weights[1][0, :, 0] = 1.0  # every action's Q = hidden unit 0
    return net


def test_impact_reward_is_change_of_partner_soft_value() -> None:
    config = ImpactConfig(envs_per_net=1, episode_steps=50)
    rollout = ParticleImpactRollout(
        [goal_index("c2")], _partner_net_valuing_ego_x(), config, seed=0
    )
    ego_x, ego_vx = 0.5, 0.0
    rollout.obs_BND = rollout.world.reset(
        np.array([[[ego_x, 0.5, ego_vx, 0.0], [0.2, 0.2, 0.0, 0.0]]])
    )
    reward, next_view = rollout.step(np.array([[4]]))  # ego pushes right
    # one step of the documented dynamics: v' = v (1 - damping) + a dt ; x' = x + v' dt
    v_next = ego_vx * (1 - DAMPING) + ACCELERATION * DT
    expected = v_next * DT
    assert reward.shape == (1, 1)
    assert reward[0, 0] == pytest.approx(expected, rel=1e-5)
    assert next_view[0, 0, 0] == pytest.approx(ego_x + expected, rel=1e-6)  # impact view: ego first

    reward_left, _ = rollout.step(np.array([[3]]))  # now push left: the ego slows down
    v_after = v_next * (1 - DAMPING) - ACCELERATION * DT
    assert reward_left[0, 0] == pytest.approx(v_after * DT, abs=1e-6)


def test_alpha_log_a_cancels_in_the_impact_reward() -> None:
    """A constant in V^h (here α log|A|) never shows up in I: resting at rest gives I = 0."""
    config = ImpactConfig(envs_per_net=1, alpha=0.3)
    rollout = ParticleImpactRollout([goal_index("a")], _partner_net_valuing_ego_x(), config, seed=0)
    rollout.obs_BND = rollout.world.reset(np.array([[[0.7, 0.5, 0.0, 0.0], [0.2, 0.2, 0.0, 0.0]]]))
    reward, _ = rollout.step(np.array([[0]]))
    assert reward[0, 0] == pytest.approx(0.0, abs=1e-7)
    assert math.isfinite(float(reward[0, 0]))
