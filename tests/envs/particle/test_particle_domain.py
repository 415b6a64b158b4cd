"""The particle Domain (views, layout) and the env registry."""

import numpy as np
import pytest

from envs.base import Domain, check_goal
from envs.particle.domain import PARTICLE
from envs.particle.env import ParticleCoexistenceEnv
from envs.particle.goals import GOAL_IDS, TARGET_BOXES_G4
from envs.particle.world import in_target, observations, perspective, step_state
from envs.registry import get_domain, make_env


def obs_of(n: int, batch: int = 3) -> np.ndarray:
    """Ego observations whose blocks are [k*10 + feature] for agent block k."""
    blocks = np.arange(n)[:, None] * 10 + np.arange(4)[None, :]
    return np.tile(blocks.reshape(-1), (batch, 1)).astype(np.float32)


def test_is_a_domain() -> None:
    assert isinstance(PARTICLE, Domain)
    assert PARTICLE.name == "particle" and len(PARTICLE.goals) == 35
    assert PARTICLE.n_actions == 5 and PARTICLE.max_agents == 5 and PARTICLE.pair_obs_dim == 8
    assert PARTICLE.obs_dim(3) == 12
    assert check_goal(PARTICLE, "c4") == 14  # column c (2) * 5 + row 4


def test_observation_layout() -> None:
    layout = PARTICLE.observation_layout(2)
    assert layout == [
        "self.x",
        "self.y",
        "self.vx",
        "self.vy",
        "other1.x",
        "other1.y",
        "other1.vx",
        "other1.vy",
    ]
    assert len(PARTICLE.observation_layout(5)) == 20


def test_task_views_pair_the_ego_with_each_other() -> None:
    views = PARTICLE.task_views(obs_of(4), 4)
    assert views.shape == (3, 3, 8)
    assert views[0, :, 0].tolist() == [0, 0, 0]  # ego block first
    assert views[0, :, 4].tolist() == [10, 20, 30]  # then other j
    np.testing.assert_array_equal(views[0, 2], [0, 1, 2, 3, 30, 31, 32, 33])


def test_single_agent_task_view_has_a_phantom_at_the_centre() -> None:
    views = PARTICLE.task_views(obs_of(1, batch=2), 1)
    assert views.shape == (2, 1, 8)
    np.testing.assert_array_equal(views[1, 0], [0, 1, 2, 3, 0.5, 0.5, 0, 0])


def test_impact_and_partner_views() -> None:
    obs = obs_of(3)
    np.testing.assert_array_equal(PARTICLE.impact_view(obs, 3, 2)[0], [0, 1, 2, 3, 20, 21, 22, 23])
    np.testing.assert_array_equal(PARTICLE.partner_view(obs, 3, 1)[0], [10, 11, 12, 13, 0, 1, 2, 3])
    for bad in (0, 3):
        with pytest.raises(ValueError, match="partner"):
            PARTICLE.impact_view(obs, 3, bad)
    with pytest.raises(ValueError, match="partner"):
        PARTICLE.partner_view(obs_of(1), 1, 1)
    with pytest.raises(ValueError, match="obs_BD"):
        PARTICLE.task_views(obs, 2)
    with pytest.raises(ValueError, match="n_agents"):
        PARTICLE.obs_dim(6)


def test_partner_view_is_the_partners_own_task_view() -> None:
    """For two agents, the (partner, ego) view equals what the partner itself observes."""
    state = np.random.default_rng(0).random((6, 2, 4))
    obs = observations(state)
    np.testing.assert_array_equal(PARTICLE.partner_view(obs[:, 0], 2, 1), obs[:, 1])
    np.testing.assert_array_equal(PARTICLE.task_views(obs[:, 1], 2)[:, 0], obs[:, 1])
    np.testing.assert_array_equal(
        PARTICLE.partner_view(obs[:, 0], 2, 1), perspective(obs[:, 0], 2, 1)
    )


def test_registry() -> None:
    assert get_domain("particle") is PARTICLE
    env = make_env("particle", ["a2", "b3", "c"], max_steps=5)
    assert isinstance(env, ParticleCoexistenceEnv) and env.max_steps == 5
    with pytest.raises(ValueError, match="particle"):
        get_domain("cooking-zoo")
    with pytest.raises(ValueError, match="unknown environment"):
        make_env("nope", ["a2"])


def _kept_by_simulation(ego_B4: np.ndarray, goal: str, rests: int = 60) -> np.ndarray:
    """(B, A): each action, then `rests` rests, stepped with the world's own dynamics: is the
    ego inside its target area after every one of those steps?"""
    goals_BA = np.full((len(ego_B4), 5), GOAL_IDS.index(goal))
    state_BA4 = step_state(
        np.repeat(ego_B4[:, None, :], 5, axis=1), np.tile(np.arange(5), (len(ego_B4), 1))
    )
    inside_BA = in_target(state_BA4, goals_BA)
    for _ in range(rests):
        state_BA4 = step_state(state_BA4, np.zeros_like(goals_BA))
        inside_BA &= in_target(state_BA4, goals_BA)
    return inside_BA


def test_goal_kept_matches_the_simulated_coast() -> None:
    rng = np.random.default_rng(12)
    partial = 0
    for goal in ["a2", "c2", "e4", "0", "c", "a0"]:
        x_lo, x_hi, y_lo, y_hi = TARGET_BOXES_G4[GOAL_IDS.index(goal)]
        # states in and near the target area (its edges), moving at up to full speed
        pos = rng.uniform([x_lo - 0.03, y_lo - 0.03], [x_hi + 0.03, y_hi + 0.03], size=(300, 2))
        vel = rng.uniform(-0.5, 0.5, size=(300, 2)) * rng.choice([0.0, 0.3, 1.0], size=(300, 1))
        ego_B4 = np.concatenate([np.clip(pos, 0, 1), vel], axis=1)
        obs = np.concatenate([ego_B4, np.full((300, 4), 0.5)], axis=1).astype(np.float32)
        kept = PARTICLE.goal_kept(obs, 2, goal)
        assert kept.shape == (300, 5) and kept.dtype == bool
        want = _kept_by_simulation(obs[:, :4].astype(np.float64), goal)
        np.testing.assert_array_equal(kept, want)
        partial += int((kept.any(axis=1) & ~kept.all(axis=1)).sum())
    assert partial > 50  # many rows where some actions keep the goal and others lose it
