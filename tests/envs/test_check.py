"""envs.check: coexist's own worlds and the corridor of tests/envs/tinyline pass; an env broken
in each way the check looks for fails with a message that names the method at fault (one test per
way), and the other checks still run."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import gymnasium
import numpy as np
import pytest

from envs.check import assert_env_conforms, check_env
from envs.registry import EnvPlugin, env_plugin, known_envs
from envs.scene import AgentMark, SceneFrame


def _failures(plugin: EnvPlugin) -> dict[str, str]:
    results = check_env(plugin, episodes=2)
    assert len(results) >= 9  # every check ran, whatever failed before it
    return {r.name: r.message for r in results if not r.passed}


@pytest.fixture
def corridor(tinyline: str) -> EnvPlugin:
    return env_plugin(tinyline)


def _domain(corridor: EnvPlugin, **methods: Any) -> Any:
    """The corridor's domain with some methods replaced."""
    base = type(corridor.domain)
    return type("Broken", (base,), methods)()


@pytest.mark.parametrize("env", known_envs())
def test_registered_envs_conform(env: str) -> None:
    assert_env_conforms(env)


def test_the_corridor_conforms(corridor: EnvPlugin) -> None:
    assert _failures(corridor) == {}


def test_an_env_pettingzoo_refuses_is_named(corridor: EnvPlugin) -> None:
    def fresh_space(self: Any, agent: str) -> Any:
        # a new space on every call: PettingZoo asks for the same object each time
        return gymnasium.spaces.Box(0.0, 1.0, (len(self.possible_agents),), np.float32)

    failures = _failures(
        replace(corridor, make_env=_env_with(corridor, observation_space=fresh_space))
    )
    assert set(failures) == {"pettingzoo"}
    assert "parallel_api_test failed" in failures["pettingzoo"]


def test_an_obs_dim_the_env_does_not_produce_is_named(corridor: EnvPlugin) -> None:
    domain = _domain(
        corridor,
        obs_dim=lambda self, n: n + 1,
        observation_layout=lambda self, n: ["x"] * (n + 1),
    )
    failures = _failures(replace(corridor, domain=domain))
    assert (
        "observation_space('agent_0'): shape (1,) with 1 agents, but obs_dim(1) = 2"
        in (failures["observations"])
    )


def test_a_layout_of_the_wrong_length_is_named(corridor: EnvPlugin) -> None:
    domain = _domain(corridor, observation_layout=lambda self, n: ["x"])
    failures = _failures(replace(corridor, domain=domain))
    assert "observation_layout(2): 1 names for obs_dim(2) = 2 features" in failures["domain"]


def test_task_views_without_the_view_axis_are_named(corridor: EnvPlugin) -> None:
    base = type(corridor.domain).task_views
    domain = _domain(corridor, task_views=lambda self, obs, n: base(self, obs, n)[:, 0])
    failures = _failures(replace(corridor, domain=domain))
    assert failures["views"].startswith("task_views(obs_BD, 1): expected floats of shape (4, 1, 2)")


def test_a_partner_view_of_integers_is_named(corridor: EnvPlugin) -> None:
    base = type(corridor.domain).partner_view
    domain = _domain(
        corridor, partner_view=lambda self, obs, n, p: base(self, obs, n, p).astype(np.int64)
    )
    failures = _failures(replace(corridor, domain=domain))
    assert failures["views"].startswith("partner_view(obs_BD, 2, 1): expected floats")
    assert "dtype int64" in failures["views"]


def test_a_partner_view_that_is_not_the_partners_own_is_named(corridor: EnvPlugin) -> None:
    # the pair as the ego sees it, not swapped: the partner's task network would see the ego as
    # itself
    domain = _domain(
        corridor,
        partner_view=lambda self, obs, n, p: np.stack([obs[:, 0], obs[:, p]], axis=-1),
    )
    failures = _failures(replace(corridor, domain=domain))
    assert set(failures) == {"perspective"}
    assert "partner_view(obs of agent 0, 2, 1)" in failures["perspective"]
    assert "differs from agent 1's own task view of agent 0" in failures["perspective"]


def test_a_goal_named_twice_is_named(corridor: EnvPlugin) -> None:
    domain = _domain(corridor, goals=("c0", "c1", "c1", "c2", "c3", "c4"))
    assert "goals: ['c1'] appear twice" in _failures(replace(corridor, domain=domain))["domain"]


def test_goal_reached_in_the_wrong_shape_is_named(corridor: EnvPlugin) -> None:
    domain = _domain(corridor, goal_reached=lambda self, obs, n, goal: np.zeros((len(obs), 1)))
    failures = _failures(replace(corridor, domain=domain))
    assert set(failures) == {"goals"}
    assert failures["goals"].startswith("goal_reached(obs_BD, 2, 'c0'): expected None or (4,) bool")


def test_a_goal_no_model_can_be_named_after_is_named(corridor: EnvPlugin) -> None:
    domain = _domain(corridor, goals=("c0", "c 1", "c2", "c3", "c4"))
    assert (
        "goals: 'c 1' cannot name a model" in _failures(replace(corridor, domain=domain))["goals"]
    )


def _env_with(corridor: EnvPlugin, **overrides: Any) -> Any:
    def make(goals: Any, **kwargs: Any) -> Any:
        env = corridor.make_env(goals, **kwargs)
        for name, method in overrides.items():
            setattr(env, name, method.__get__(env))
        return env

    return make


def test_a_reward_that_is_not_a_number_is_named(corridor: EnvPlugin) -> None:
    step = type(corridor.make_env(("c0", "c1"))).step

    def nan_reward(self: Any, actions: Any) -> Any:
        obs, rewards, *rest = step(self, actions)
        return (obs, dict.fromkeys(rewards, float("nan")), *rest)

    failures = _failures(replace(corridor, make_env=_env_with(corridor, step=nan_reward)))
    assert "step: 'agent_0''s reward nan is not a finite number" in failures["episodes"]


def test_a_reset_that_ignores_its_seed_is_named(corridor: EnvPlugin) -> None:
    reset = type(corridor.make_env(("c0", "c1"))).reset
    draws = iter(range(10**6))

    def unseeded(self: Any, seed: Any = None, options: Any = None) -> Any:
        return reset(self, seed=next(draws), options=options)

    failures = _failures(replace(corridor, make_env=_env_with(corridor, reset=unseeded)))
    assert failures["episodes"].startswith("reset(seed=0): the same seed and actions gave another")


def test_an_env_that_ignores_max_steps_is_named(corridor: EnvPlugin) -> None:
    def endless(goals: Any, **kwargs: Any) -> Any:
        return corridor.make_env(goals, max_steps=10**6)

    failures = _failures(replace(corridor, make_env=endless))
    assert (
        "did not end within max_steps=50 (make_env must honour max_steps)" in (failures["episodes"])
    )


def test_a_frame_that_is_not_json_is_named(corridor: EnvPlugin) -> None:
    class Drawing:
        def scene(self, env: Any) -> Any:
            return corridor.drawing.scene(env)  # type: ignore[union-attr]

        def scene_frame(self, env: Any) -> SceneFrame:
            return SceneFrame((AgentMark(0, float("nan"), 0.5, "agent 0"),))

    failures = _failures(replace(corridor, drawing=Drawing()))
    assert set(failures) == {"drawing"}
    assert failures["drawing"].startswith("scene_frame(env) is not JSON the console can stream")
    assert "agent 0: x: expected a finite number" in failures["drawing"]


def test_a_training_that_does_not_resolve_is_named(corridor: EnvPlugin) -> None:
    failures = _failures(replace(corridor, training="tinyline.nowhere:TRAINING"))
    assert set(failures) == {"training"}
    assert "'tinyline.nowhere:TRAINING' does not resolve" in failures["training"]


def test_the_pytest_helper_lists_every_failure(corridor: EnvPlugin) -> None:
    broken = replace(corridor, training="nowhere:X", domain=_domain(corridor, goals=("c0", "c0")))
    with pytest.raises(AssertionError, match=r"(?s)does not conform.*- domain: .*- training: "):
        assert_env_conforms(broken)
