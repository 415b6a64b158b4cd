"""Cooking rollouts on hand-built kitchens: shapes, the dish reward, restarts and eq. 6."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from envs.cooking import get_layout, perspective
from envs.cooking.recipes import CHOPPED
from envs.cooking.world import CookingState, start_states
from policy.qnet import QNetSpec, StackedQNet
from trainer.cooking.config import CookingImpactConfig, CookingTaskConfig
from trainer.cooking.kitchens import Kitchens, training_kitchen
from trainer.cooking.rollouts import CookingImpactRollout, CookingTaskRollout

# coexistence objects in reading order: tomato, lettuce, banana, carrot, plate (1,10), plate (4,1)
TOMATO, LETTUCE, BANANA, CARROT, RIGHT_PLATE, LEFT_PLATE = range(6)
DOWN, STAY = 2, 0
SMALL = dict(envs_per_net=2, pool_episodes=2, pool_steps=6, linger_steps=3, episode_steps=30)


def _dish_ready(n_envs: int) -> CookingState:
    """Left cook at (3, 2) holding a plate with chopped tomato + lettuce, the delivery square
    (4, 2) just below; right cook at (3, 7) holding a plate with chopped carrot + banana, the
    right delivery square (4, 7) just below."""
    s = start_states(get_layout("coexistence"), n_envs)
    s.agent_rc[:, 0], s.agent_rc[:, 1] = (3, 2), (3, 7)
    s.obj_holder[:, LEFT_PLATE], s.obj_holder[:, RIGHT_PLATE] = 0, 1
    for item, plate in (
        (TOMATO, LEFT_PLATE),
        (LETTUCE, LEFT_PLATE),
        (CARROT, RIGHT_PLATE),
        (BANANA, RIGHT_PLATE),
    ):
        s.obj_plate[:, item], s.obj_state[:, item] = plate, CHOPPED
    return s


def test_training_kitchens_seat_the_fig8_cooks() -> None:
    assert training_kitchen("TomatoLettuceSalad").seat == 0
    assert training_kitchen("CarrotBanana").seat == 1
    assert training_kitchen("CarrotBanana").handover == "carrot"
    with pytest.raises(ValueError, match="unknown recipe"):
        training_kitchen("Pizza")


def test_a_served_dish_pays_20_minus_the_step_then_the_kitchen_lingers_and_restarts() -> None:
    cfg = replace(CookingTaskConfig(), **SMALL, scripted_start_prob=0.0, random_starts=False)  # type: ignore[arg-type]
    k = Kitchens("TomatoLettuceSalad", 2, cfg, seed=0)
    k.start_from(_dish_ready(2))
    out = k.step(np.array([[DOWN, STAY], [STAY, STAY]]))
    assert out.next_obs_BND.shape == (2, 2, 188) and out.next_obs_BND.dtype == np.float32
    np.testing.assert_allclose(out.unshaped_BN[:, 0], [19.99, -0.01])
    np.testing.assert_allclose(out.rewards_BN[:, 0], [19.99, -0.01])  # no sub-goal left to earn
    assert not out.done_B.any()
    for _ in range(cfg.linger_steps - 1):
        out = k.step(np.zeros((2, 2), dtype=np.int64))
        assert out.unshaped_BN[0, 0] == 0.0  # served: no more time penalty
        assert not out.done_B.any()
    out = k.step(np.zeros((2, 2), dtype=np.int64))
    assert out.done_B.tolist() == [True, False]
    # the restarted kitchen is the layout's start, the other one is untouched
    assert k.world.state.agent_rc[0].tolist() == [[2, 2], [2, 8]]
    assert k.world.state.agent_rc[1].tolist() == [[3, 2], [3, 7]]
    assert not k.world.state.delivered[0].any() and k.steps_B.tolist() == [0, cfg.linger_steps + 1]


def test_task_rollout_shapes_and_reward_of_the_learner_seat() -> None:
    cfg = replace(CookingTaskConfig(), **SMALL)  # type: ignore[arg-type]
    rollout = CookingTaskRollout(["TomatoLettuceSalad", "CarrotBanana"], cfg, seed=1)
    views = rollout.observe()
    assert views.shape == (2, 2, 188) and views.dtype == np.float32
    for k in rollout.kitchens:
        k.start_from(_dish_ready(2))
    # the CarrotBanana learner sits on the right (seat 1): its view starts with its own block
    right = rollout.observe()[1]
    np.testing.assert_array_equal(right, rollout.kitchens[1].obs_BND[:, 1])
    reward_GE, next_GED = rollout.step(np.array([[DOWN, STAY], [DOWN, STAY]]))
    assert reward_GE.shape == (2, 2) and next_GED.shape == (2, 2, 188)
    np.testing.assert_allclose(reward_GE[:, 0], [19.99, 19.99], atol=1e-6)
    np.testing.assert_allclose(reward_GE[:, 1], [-0.01, -0.01], atol=1e-6)


def _bias_net(bias_A: list[float]) -> StackedQNet:
    """A one-member network whose Q-values are `bias_A` whatever the view."""
    net = StackedQNet(QNetSpec(obs_dim=188, n_actions=5, hidden=(4,)), 1)
    with torch.no_grad():
        for w, b in zip(net.weights, net.biases, strict=True):
            w.zero_()
            b.zero_()
        net.biases[-1][0] = torch.tensor(bias_A)
    return net


@pytest.mark.parametrize("variant", ["value_change", "value_change_plus_reward"])
def test_impact_reward_adds_the_partner_reward_only_when_asked(variant: str) -> None:
    cfg = replace(CookingImpactConfig(), **SMALL, impact_reward=variant)  # type: ignore[arg-type]
    partner = _bias_net([0.0, 0.0, 10.0, 0.0, 0.0])  # always walks down: serves its dish
    rollout = CookingImpactRollout(["CarrotBanana"], partner, cfg, seed=2)
    rollout.kitchens[0].start_from(_dish_ready(2))
    impact_GE, _ = rollout.step(np.zeros((1, 2), dtype=np.int64))
    # V is constant (the Q-values do not depend on the view), so only the reward can show
    expected = 19.99 if variant == "value_change_plus_reward" else 0.0
    np.testing.assert_allclose(impact_GE, [[expected, expected]], atol=1e-4)


def test_impact_reward_is_the_change_of_the_partners_soft_value_on_its_own_view() -> None:
    cfg = replace(CookingImpactConfig(), **SMALL, impact_reward="value_change")  # type: ignore[arg-type]
    partner = StackedQNet(
        QNetSpec(obs_dim=188, n_actions=5, hidden=(8,)),
        1,
        generator=torch.Generator().manual_seed(0),
    )
    rollout = CookingImpactRollout(["CarrotBanana"], partner, cfg, seed=3)
    k = rollout.kitchens[0]
    before = k.obs_BND[:, 1].copy()  # the partner (right cook)'s own observation
    actions = np.array([[4, 1]])  # the ego (left cook) walks right / up
    impact_GE, next_view_GED = rollout.step(actions)
    after = perspective(next_view_GED[0], 2, 1)  # the partner's next observation

    def soft_value(obs: np.ndarray) -> np.ndarray:  # eq. 3 in float64, by hand
        with torch.no_grad():
            q = partner(torch.from_numpy(obs)[None])[0].double().numpy()
        return cfg.alpha * np.log(np.exp(q / cfg.alpha).sum(axis=1))

    np.testing.assert_allclose(impact_GE[0], soft_value(after) - soft_value(before), atol=1e-4)
    # the learner's view is its own (left cook's) observation
    np.testing.assert_array_equal(next_view_GED[0], k.world.observe()[:, 0])


@pytest.mark.parametrize("first_prob", [0.0, 1.0])
def test_helper_hands_over_first_or_after_its_own_dish(first_prob: float) -> None:
    settings = {
        **SMALL,
        "episode_steps": 60,
        "handover_first_prob": first_prob,
        "handover_delay_max": 5,
        "scripted_start_prob": 0.0,
    }
    cfg = replace(CookingTaskConfig(), **settings)  # type: ignore[arg-type]
    k = Kitchens("CarrotBanana", 2, cfg, seed=0)
    if first_prob == 0.0:
        assert (k.delay_B == -1).all()
    else:
        assert ((k.delay_B >= 0) & (k.delay_B <= 5)).all()
    carried_at = np.full(2, -1)
    for t in range(40):
        actions = np.zeros((2, 2), dtype=np.int64)
        actions[:, 0] = k.scripted_other(0.0)
        k.step(actions)
        held_B = k.world.state.obj_holder[:, CARROT] == 0
        carried_at[(carried_at < 0) & held_B] = t
    salad_done_B = k.world.state.delivered[:, 0]
    if first_prob == 0.0:  # the salad (>= 20 steps) comes before the carrot
        assert salad_done_B.all() and (carried_at >= 20).all()
    else:  # the carrot is picked up within a few steps of the hand-over step
        assert (carried_at >= 0).all() and (carried_at <= 15).all()
