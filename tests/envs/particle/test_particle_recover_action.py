"""ParticleDomain.recover_action: step a random state with each action, recover the partner's
action from the two ego observations; ties (walls, a state beyond the speed cap) go to the lowest
action index; bad arguments name themselves."""

from __future__ import annotations

import numpy as np
import pytest

from envs.particle.domain import PARTICLE
from envs.particle.world import MAX_SPEED, N_ACTIONS, observations, step_state


def _valid_states(rng: np.random.Generator, n_agents: int) -> np.ndarray:
    """Positions anywhere in the square (walls included), velocities up to the speed cap."""
    state = np.zeros((n_agents, 4))
    state[:, :2] = rng.random((n_agents, 2))
    walls = rng.choice([0.0, 1.0], (n_agents, 2))
    state[:, :2] = np.where(rng.random((n_agents, 2)) < 0.15, walls, state[:, :2])  # some at a wall
    angle = rng.uniform(0, 2 * np.pi, n_agents)
    speed = rng.uniform(0, MAX_SPEED, n_agents) * (rng.random(n_agents) > 0.2)
    state[:, 2], state[:, 3] = speed * np.cos(angle), speed * np.sin(angle)
    return state


def _ego_obs(state_N4: np.ndarray) -> np.ndarray:
    return observations(state_N4)[0]  # agent 0 is the ego


def _expected(before_4: np.ndarray, action: int) -> int:
    """The action itself, or the lowest action that predicts the very same next state."""
    predicted = step_state(np.repeat(before_4[None, None], N_ACTIONS, 0), np.arange(5)[:, None])
    same = [
        a
        for a in range(N_ACTIONS)
        if np.allclose(predicted[a], predicted[action], rtol=0, atol=1e-9)
    ]
    return min(same)


def test_every_action_comes_back_from_random_states() -> None:
    rng = np.random.default_rng(11)
    distinguishable = ties = 0
    for _ in range(200):
        n_agents = int(rng.integers(2, 6))
        state = _valid_states(rng, n_agents)
        partner = int(rng.integers(1, n_agents))  # the ego's layout: agent j is at block j
        for action in range(N_ACTIONS):
            actions = rng.integers(0, N_ACTIONS, n_agents)  # the others do anything
            actions[partner] = action
            after = step_state(state, actions)
            got = PARTICLE.recover_action(_ego_obs(state), _ego_obs(after), n_agents, partner)
            expected = _expected(state[partner], action)
            assert got == expected, (state[partner], action)
            distinguishable += expected == action
            ties += expected != action
    assert distinguishable > 900  # most states tell every action apart
    assert ties > 0  # and the walls produce some ties (checked above: lowest index)


def test_float32_observations_still_recover_the_action() -> None:
    rng = np.random.default_rng(5)
    for _ in range(100):
        state = _valid_states(rng, 2)
        state[:, :2] = np.clip(state[:, :2], 0.05, 0.95)  # away from the walls: no ties
        for action in range(N_ACTIONS):
            after = step_state(state, np.array([0, action]))
            before_obs = _ego_obs(state).astype(np.float32)
            after_obs = _ego_obs(after).astype(np.float32)
            assert PARTICLE.recover_action(before_obs, after_obs, 2, 1) == action


def test_pushing_into_a_wall_at_rest_is_indistinguishable_from_rest() -> None:
    # at x = 0 at rest, "left" moves to x = -0.02, clipped back to 0 with vx zeroed: as "rest"
    state = np.array([[0.5, 0.5, 0.0, 0.0], [0.0, 0.4, 0.0, 0.0]])
    for action, expected in ((0, 0), (3, 0), (1, 1), (2, 2), (4, 4)):
        after = step_state(state, np.array([0, action]))
        assert PARTICLE.recover_action(_ego_obs(state), _ego_obs(after), 2, 1) == expected
    left = step_state(state, np.array([0, 3]))
    rest = step_state(state, np.array([0, 0]))
    np.testing.assert_array_equal(left, rest)  # the tie is real


def test_beyond_the_speed_cap_rest_and_a_push_along_the_motion_tie() -> None:
    # vx = 1.0 (twice the cap; unreachable, but a client may send it): rest damps it to 0.75,
    # "right" makes it 0.95 and "left" 0.55; all three are capped to 0.5 along x, so the next
    # states are equal -> rest (0). "up" turns the velocity: a different state.
    state = np.array([[0.5, 0.5, 0.0, 0.0], [0.3, 0.5, 1.0, 0.0]])
    rest = step_state(state, np.array([0, 0]))
    for push in (3, 4):
        after = step_state(state, np.array([0, push]))
        np.testing.assert_allclose(after, rest, rtol=0, atol=1e-15)
        assert PARTICLE.recover_action(_ego_obs(state), _ego_obs(after), 2, 1) == 0
    up = step_state(state, np.array([0, 1]))
    assert PARTICLE.recover_action(_ego_obs(state), _ego_obs(up), 2, 1) == 1


def test_a_noisy_next_state_goes_to_the_nearest_prediction() -> None:
    state = np.array([[0.5, 0.5, 0.0, 0.0], [0.3, 0.3, 0.1, 0.0]])
    up = step_state(state, np.array([0, 1]))
    noisy = _ego_obs(up) + np.random.default_rng(0).normal(0, 0.01, 8)
    assert PARTICLE.recover_action(_ego_obs(state), noisy, 2, 1) == 1


def test_bad_arguments_name_themselves() -> None:
    obs = np.zeros(8)
    with pytest.raises(ValueError, match=r"^partner:"):
        PARTICLE.recover_action(obs, obs, 2, 2)
    with pytest.raises(ValueError, match=r"^partner:"):
        PARTICLE.recover_action(obs, obs, 2, 0)
    with pytest.raises(ValueError, match=r"^obs_BD:"):
        PARTICLE.recover_action(np.zeros(7), obs, 2, 1)
