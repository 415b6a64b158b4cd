"""The batched simulator: shapes, termination/truncation, reset_where, determinism, and equality
with the PettingZoo env step for step."""

import numpy as np
import pytest

from envs.particle.batched import BatchedParticleWorld
from envs.particle.env import ParticleCoexistenceEnv
from envs.particle.goals import goal_index
from envs.particle.world import observations, rewards, step_state


def test_shapes_and_true_next_observation() -> None:
    world = BatchedParticleWorld(np.array([[0, 1, 2]] * 4), seed=0)
    obs = world.reset()
    assert obs.shape == (4, 3, 12) and obs.dtype == np.float32
    before = world.state
    actions = np.random.default_rng(0).integers(0, 5, size=(4, 3))
    res = world.step(actions)
    after = step_state(before, actions)
    np.testing.assert_allclose(world.state, after)
    np.testing.assert_allclose(res.next_obs_BND, observations(after).astype(np.float32))
    np.testing.assert_allclose(res.rewards_BN, rewards(after, world.goals))
    assert res.terminated_B.shape == res.truncated_B.shape == (4,)


def test_terminated_when_every_agent_is_in_its_target() -> None:
    g = np.array([[goal_index("a2"), goal_index("b3")]] * 2)
    world = BatchedParticleWorld(g, seed=0)
    start = np.zeros((2, 2, 4))
    start[0] = [[0.1, 0.5, 0, 0], [0.3, 0.7, 0, 0]]  # both inside
    start[1] = [[0.1, 0.5, 0, 0], [0.9, 0.9, 0, 0]]  # partner outside
    world.reset(start)
    res = world.step(np.zeros((2, 2), dtype=int))
    assert res.terminated_B.tolist() == [True, False]
    assert not res.truncated_B.any()


def test_truncation_and_reset_where() -> None:
    world = BatchedParticleWorld(np.array([[goal_index("e4")]] * 3), max_steps=3, seed=1)
    world.reset(np.tile([[[0.0, 0.0, 0.0, 0.0]]], (3, 1, 1)))
    for _ in range(2):
        assert not world.step(np.zeros((3, 1), dtype=int)).truncated_B.any()
    res = world.step(np.zeros((3, 1), dtype=int))
    assert res.truncated_B.all() and not res.terminated_B.any()
    kept = world.state[1]
    world.reset_where(np.array([True, False, True]))
    assert world.steps.tolist() == [0, 3, 0]
    np.testing.assert_array_equal(world.state[1], kept)
    assert not np.array_equal(world.state[0], world.state[2])
    assert np.all(world.state[[0, 2], :, 2:] == 0)


def test_deterministic_given_seed() -> None:
    def run(seed: int) -> list[np.ndarray]:
        world = BatchedParticleWorld(np.array([[3, 30]] * 5), max_steps=4, seed=seed)
        out = [world.reset()]
        rng = np.random.default_rng(9)
        for _ in range(10):
            res = world.step(rng.integers(0, 5, size=(5, 2)))
            out += [res.next_obs_BND, world.reset_where(res.truncated_B | res.terminated_B)]
        return out

    for a, b in zip(run(3), run(3), strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(run(3)[0], run(4)[0])


def test_set_goals_and_bad_input() -> None:
    world = BatchedParticleWorld(np.array([[0, 1]]), seed=0)
    world.set_goals(np.array([[34, 2]]))
    assert world.goals.tolist() == [[34, 2]]
    with pytest.raises(ValueError, match="goals_BN"):
        world.set_goals(np.array([[1, 2, 3]]))
    with pytest.raises(ValueError, match="goals_BN"):
        BatchedParticleWorld(np.array([[35]]))
    with pytest.raises(ValueError, match="goals_BN"):
        BatchedParticleWorld(np.zeros((2, 6), dtype=int))
    with pytest.raises(ValueError, match="states_BN4"):
        world.reset(np.zeros((1, 3, 4)))
    with pytest.raises(ValueError, match="actions"):
        world.step(np.zeros((1, 3), dtype=int))
    with pytest.raises(ValueError, match="mask_B"):
        world.reset_where(np.array([True, False]))


@pytest.mark.parametrize("goals", [("a2",), ("a2", "b3"), ("a2", "a0", "b2", "c4", "e1")])
def test_batched_equals_pettingzoo_env(goals: tuple[str, ...]) -> None:
    n = len(goals)
    rng = np.random.default_rng(5)
    start = np.concatenate([rng.random((n, 2)), np.zeros((n, 2))], axis=1)
    env = ParticleCoexistenceEnv(goals=goals, max_steps=60)
    obs_env, _ = env.reset(seed=0, options={"state": start})
    world = BatchedParticleWorld(np.array([[goal_index(g) for g in goals]]), max_steps=60)
    obs_world = world.reset(start[None])
    for i, agent in enumerate(env.possible_agents):
        np.testing.assert_array_equal(obs_env[agent], obs_world[0, i])
    while env.agents:
        actions = rng.integers(0, 5, size=n)
        obs_env, rew_env, term_env, trunc_env, _ = env.step(
            {a: int(actions[i]) for i, a in enumerate(env.possible_agents)}
        )
        res = world.step(actions[None])
        for i, agent in enumerate(env.possible_agents):
            np.testing.assert_array_equal(obs_env[agent], res.next_obs_BND[0, i])
            assert rew_env[agent] == res.rewards_BN[0, i]
            assert term_env[agent] == res.terminated_B[0]
            assert trunc_env[agent] == res.truncated_B[0]
        np.testing.assert_array_equal(env.state(), world.state[0].reshape(-1).astype(np.float32))
    assert world.steps[0] <= 60
