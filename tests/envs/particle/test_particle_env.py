"""The PettingZoo env: conformance tests for N = 1..5, spaces, options, infos, errors, render."""

import functools
import math

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from envs.particle.env import ParticleCoexistenceEnv, parallel_env

GOALS_BY_N = {
    1: ("a2",),
    2: ("a2", "b3"),
    3: ("c", "c4", "0"),
    4: ("a0", "b1", "c2", "d3"),
    5: ("a2", "a0", "b2", "c4", "e1"),
}


@pytest.mark.parametrize("n", sorted(GOALS_BY_N))
def test_pettingzoo_conformance(n: int) -> None:
    parallel_api_test(parallel_env(goals=GOALS_BY_N[n]), num_cycles=1000)
    parallel_seed_test(functools.partial(parallel_env, goals=GOALS_BY_N[n]))


def test_spaces_and_observations_are_within_bounds() -> None:
    env = ParticleCoexistenceEnv(goals=GOALS_BY_N[3], max_steps=200)
    obs, infos = env.reset(seed=3)
    assert env.possible_agents == ["agent_0", "agent_1", "agent_2"]
    space = env.observation_space("agent_1")
    assert space.shape == (12,)
    assert space.low[:4].tolist() == [0, 0, -0.5, -0.5]
    assert env.action_space("agent_2").n == 5
    rng = np.random.default_rng(0)
    while env.agents:
        for agent, o in obs.items():
            assert env.observation_space(agent).contains(o)
        obs, *_ = env.step({a: int(rng.integers(0, 5)) for a in env.agents})
    assert infos["agent_2"]["goal"] == "0"


def test_start_state_option_and_infos() -> None:
    env = ParticleCoexistenceEnv(goals=("a2", "b3"))
    start = np.array([[0.1, 0.5, 0.0, 0.0], [0.9, 0.9, 0.1, 0.0]])
    obs, infos = env.reset(options={"state": start})
    np.testing.assert_allclose(env.state(), start.reshape(-1))
    np.testing.assert_allclose(obs["agent_1"], np.concatenate([start[1], start[0]]))
    assert infos == {
        "agent_0": {"goal": "a2", "in_target": True},
        "agent_1": {"goal": "b3", "in_target": False},
    }


def test_episode_terminates_when_all_are_inside() -> None:
    env = ParticleCoexistenceEnv(goals=("a2", "b3"))
    env.reset(options={"state": np.array([[0.1, 0.5, 0, 0], [0.3, 0.7, 0, 0]])})
    _, rewards, terminated, truncated, _ = env.step({"agent_0": 0, "agent_1": 0})
    assert rewards["agent_0"] == pytest.approx(-math.hypot(0.5, 0.1))  # partner vs. influence e2
    assert terminated == {"agent_0": True, "agent_1": True}
    assert truncated == {"agent_0": False, "agent_1": False}
    assert env.agents == []
    with pytest.raises(ValueError, match="reset"):
        env.step({"agent_0": 0, "agent_1": 0})


def test_same_seed_same_start() -> None:
    a, b = ParticleCoexistenceEnv(), ParticleCoexistenceEnv()
    a.reset(seed=11)
    b.reset(seed=11)
    np.testing.assert_array_equal(a.state(), b.state())
    b.reset(seed=12)
    assert not np.array_equal(a.state(), b.state())


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"goals": ()}, "goals"),
        ({"goals": ("a0",) * 6}, "goals"),
        ({"goals": "a0"}, "goals"),
        ({"goals": ("a0", "z9")}, "z9"),
        ({"render_mode": "human"}, "render_mode"),
    ],
)
def test_bad_construction(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        ParticleCoexistenceEnv(**kwargs)


def test_bad_reset_and_step_input() -> None:
    env = ParticleCoexistenceEnv(goals=("a2", "b3"))
    with pytest.raises(ValueError, match="state"):
        env.reset(options={"state": np.zeros((3, 4))})
    with pytest.raises(ValueError, match="positions"):
        env.reset(options={"state": np.array([[1.5, 0, 0, 0], [0, 0, 0, 0]])})
    with pytest.raises(ValueError, match="speeds"):
        env.reset(options={"state": np.array([[0.5, 0, 0.9, 0], [0, 0, 0, 0]])})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="agent_1"):
        env.step({"agent_0": 0})
    with pytest.raises(ValueError, match="actions"):
        env.step({"agent_0": 0, "agent_1": 7})


def test_render() -> None:
    env = ParticleCoexistenceEnv(goals=("a2", "b3"), render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame is not None and frame.shape == (480, 480, 3) and frame.dtype == np.uint8
    with pytest.warns(UserWarning, match="render_mode"):
        assert ParticleCoexistenceEnv().render() is None
