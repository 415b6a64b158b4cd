"""Pure world functions: dynamics, box distance, reward, observations, perspective."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from envs.particle.goals import goal_index
from envs.particle.world import (
    DAMPING,
    MAX_SPEED,
    box_distance,
    from_perspective,
    in_target,
    observations,
    perspective,
    random_states,
    rewards,
    step_state,
)

REST, UP, DOWN, LEFT, RIGHT = range(5)


def state(*agents: tuple[float, float, float, float]) -> np.ndarray:
    return np.array([agents], dtype=np.float64)  # (1, N, 4)


def goals(*ids: str) -> np.ndarray:
    return np.array([[goal_index(g) for g in ids]])


# --- dynamics ---------------------------------------------------------------------------------


def test_one_push_from_rest() -> None:
    # v' = 0.75 * 0 + 2.0 * 0.1 = 0.2 ; x' = 0.5 + 0.2 * 0.1
    nxt = step_state(state((0.5, 0.5, 0.0, 0.0)), np.array([[RIGHT]]))
    np.testing.assert_allclose(nxt[0, 0], [0.52, 0.5, 0.2, 0.0])
    nxt = step_state(state((0.5, 0.5, 0.0, 0.0)), np.array([[DOWN]]))
    np.testing.assert_allclose(nxt[0, 0], [0.5, 0.48, 0.0, -0.2])


def test_rest_decays_speed_geometrically() -> None:
    s = state((0.5, 0.5, 0.3, -0.2))
    for k in range(1, 6):
        s = step_state(s, np.array([[REST]]))
        np.testing.assert_allclose(s[0, 0, 2:], np.array([0.3, -0.2]) * (1 - DAMPING) ** k)


def test_speed_is_capped() -> None:
    s = state((0.5, 0.5, 0.0, 0.0))
    for k in range(40):
        s = step_state(s, np.array([[UP if k % 2 else RIGHT]]))
        assert np.linalg.norm(s[0, 0, 2:]) <= MAX_SPEED + 1e-12
        s[0, 0, :2] = 0.5  # keep away from the walls
    s = step_state(state((0.5, 0.5, 0.5, 0.0)), np.array([[RIGHT]]))
    assert s[0, 0, 2] == pytest.approx(MAX_SPEED)


def test_walls_clip_position_and_zero_the_velocity_into_them() -> None:
    s = step_state(state((0.99, 0.01, 0.4, -0.4)), np.array([[RIGHT]]))
    assert s[0, 0, 0] == 1.0 and s[0, 0, 2] == 0.0
    assert s[0, 0, 1] == 0.0 and s[0, 0, 3] == 0.0
    # moving along a wall keeps that velocity component
    s = step_state(state((0.0, 0.5, 0.0, 0.3)), np.array([[LEFT]]))
    assert s[0, 0, 0] == 0.0 and s[0, 0, 2] == 0.0 and s[0, 0, 3] > 0


def steps_until(s: np.ndarray, action_of_step, done) -> int:
    for n in range(1, 200):
        s = step_state(s, np.array([[action_of_step(n)]]))
        if done(s[0, 0]):
            return n
    raise AssertionError("never arrived")


def test_crossing_time_is_a_few_dozen_steps() -> None:
    start = state((0.0, 0.0, 0.0, 0.0))
    side = steps_until(start, lambda n: RIGHT, lambda a: a[0] >= 1.0)
    diagonal = steps_until(
        start, lambda n: RIGHT if n % 2 else UP, lambda a: a[0] >= 1.0 and a[1] >= 1.0
    )
    assert side == 21  # documented in world.py
    assert 25 <= diagonal <= 40


def test_bad_actions_are_rejected() -> None:
    with pytest.raises(ValueError, match="actions"):
        step_state(state((0.5, 0.5, 0, 0)), np.array([[5]]))
    with pytest.raises(ValueError, match="actions"):
        step_state(state((0.5, 0.5, 0, 0)), np.array([0, 1]))
    with pytest.raises(ValueError, match="state"):
        step_state(np.zeros((2, 3)), np.array([0, 1]))


# --- distances and reward ---------------------------------------------------------------------


def test_box_distance_hand_cases() -> None:
    boxes = np.array([0.2, 0.4, 0.6, 0.8])
    points = np.array([[0.3, 0.7], [0.2, 0.8], [0.5, 0.7], [0.0, 0.0], [0.7, 1.0]])
    np.testing.assert_allclose(
        box_distance(points, boxes), [0.0, 0.0, 0.1, math.hypot(0.2, 0.6), math.hypot(0.3, 0.2)]
    )


def test_reward_zero_when_in_target_and_partner_in_influence() -> None:
    # ego a2 (target x<=.2, .4<=y<=.6; influence e2), partner b3 (target b3; influence d1)
    s = state((0.1, 0.5, 0.0, 0.0), (0.9, 0.5, 0.0, 0.0))
    r = rewards(s, goals("a2", "b3"))
    assert r[0, 0] == 0.0
    # partner: its distance to b3 is hypot(0.5, 0.1), and so is the ego's distance to d1
    assert r[0, 1] == pytest.approx(-2 * math.hypot(0.5, 0.1))


def test_reward_known_distances_three_agents() -> None:
    s = state((0.5, 0.5, 0, 0), (0.1, 0.1, 0, 0), (0.95, 0.3, 0, 0))
    g = goals("c4", "a", "3")
    r = rewards(s, g)
    # agent 0: target c4 -> 0.3 ; influence c0: agent 1 0.3, agent 2 hypot(0.35, 0.1)
    assert r[0, 0] == pytest.approx(-0.3 - 0.3 - math.hypot(0.35, 0.1))
    # agent 1: target a -> 0 ; influence e: agent 0 0.3, agent 2 0
    assert r[0, 1] == pytest.approx(-0.3)
    # agent 2: target row 3 -> 0.3 ; influence row 1 (0.2 <= y <= 0.4): agents 0 and 1 0.1 each
    assert r[0, 2] == pytest.approx(-0.3 - 0.1 - 0.1)


def naive_rewards(state_N4: np.ndarray, goal_ids: list[str]) -> list[float]:
    from envs.particle.goals import INFLUENCE_BOXES_G4, TARGET_BOXES_G4

    def dist(p, b):
        dx = max(b[0] - p[0], 0.0, p[0] - b[1])
        dy = max(b[2] - p[1], 0.0, p[1] - b[3])
        return math.sqrt(dx * dx + dy * dy)

    out = []
    for i, gi in enumerate(goal_ids):
        r = -dist(state_N4[i], TARGET_BOXES_G4[goal_index(gi)])
        for j in range(len(goal_ids)):
            if j != i:
                r -= dist(state_N4[j], INFLUENCE_BOXES_G4[goal_index(gi)])
        out.append(r)
    return out


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 5), st.integers(0, 2**32 - 1))
def test_reward_matches_naive_loop(n: int, seed: int) -> None:
    from envs.particle.goals import GOAL_IDS

    rng = np.random.default_rng(seed)
    s = random_states(rng, (3,), n)
    g = rng.integers(0, 35, size=(3, n))
    r = rewards(s, g)
    for b in range(3):
        expected = naive_rewards(s[b], [GOAL_IDS[k] for k in g[b]])
        np.testing.assert_allclose(r[b], expected, atol=1e-12)
    assert np.all(r <= 0.0)


def test_in_target_includes_the_border() -> None:
    s = state((0.2, 0.5, 0, 0), (0.2000001, 0.5, 0, 0))
    assert in_target(s, goals("a2", "a2")).tolist() == [[True, False]]


# --- observations and perspective -------------------------------------------------------------


def test_observation_layout() -> None:
    s = np.arange(12, dtype=np.float64).reshape(1, 3, 4)
    obs = observations(s)
    assert obs.shape == (1, 3, 12)
    blocks = obs.reshape(3, 3, 4)[:, :, 0]  # first feature of each block identifies the agent
    assert blocks.tolist() == [[0, 4, 8], [4, 0, 8], [8, 0, 4]]


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 5), st.data())
def test_perspective_of_agent_0_is_the_true_observation(n: int, data: st.DataObject) -> None:
    i = data.draw(st.integers(0, n - 1))
    s = random_states(np.random.default_rng(data.draw(st.integers(0, 999))), (4,), n)
    obs = observations(s)
    np.testing.assert_array_equal(perspective(obs[:, 0], n, i), obs[:, i])
    # round trip in both directions
    np.testing.assert_array_equal(from_perspective(perspective(obs[:, 0], n, i), n, i), obs[:, 0])
    other = obs[:, n - 1]
    np.testing.assert_array_equal(perspective(from_perspective(other, n, i), n, i), other)


def test_perspective_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="agent"):
        perspective(np.zeros((1, 8)), 2, 2)
    with pytest.raises(ValueError, match="obs"):
        perspective(np.zeros((1, 9)), 2, 1)


def test_random_states() -> None:
    s = random_states(np.random.default_rng(0), (7, 3), 2)
    assert s.shape == (7, 3, 2, 4)
    assert np.all((s[..., :2] >= 0) & (s[..., :2] <= 1)) and np.all(s[..., 2:] == 0)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 5), st.integers(0, 2**32 - 1))
def test_step_keeps_agents_in_the_world_and_under_the_speed_cap(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    s = random_states(rng, (8,), n)
    speed = rng.random((8, n)) * MAX_SPEED
    angle = rng.random((8, n)) * 2 * np.pi
    s[..., 2], s[..., 3] = speed * np.cos(angle), speed * np.sin(angle)
    for _ in range(5):
        s = step_state(s, rng.integers(0, 5, size=(8, n)))
        assert np.all((s[..., :2] >= 0.0) & (s[..., :2] <= 1.0))
        assert np.all(np.linalg.norm(s[..., 2:], axis=-1) <= MAX_SPEED + 1e-12)
        assert np.all(np.isfinite(s))
