"""Scenario helpers and the scripted straight-to-target controller."""

import numpy as np
import pytest

from envs.particle.goals import GOAL_IDS
from envs.particle.scenarios import (
    ALIGNED_PAIR,
    FIVE_AGENTS,
    NON_ALIGNED_PAIR,
    is_aligned,
    sample_goal_pairs,
    start_states,
)
from envs.particle.scripted import scripted_actions
from envs.particle.world import in_target, random_states, step_state


def test_paper_scenarios() -> None:
    assert is_aligned(*ALIGNED_PAIR)
    assert not is_aligned(*NON_ALIGNED_PAIR)
    ego, partners = FIVE_AGENTS
    assert len(partners) == 4 and not any(is_aligned(ego, p) for p in partners)


@pytest.mark.parametrize(
    ("ego", "partner", "aligned"),
    [
        ("c0", "c4", True),  # influence of c4 is c0
        ("c1", "c4", False),
        ("e2", "a2", True),
        ("0", "a4", True),  # row 0 contains a0
        ("b", "b", False),  # column b mirrors to column d
        ("c", "c", True),
        ("a0", "d4", False),  # b0 touches a0 along an edge only: no area
        ("2", "c", True),
    ],
)
def test_is_aligned_cases(ego: str, partner: str, aligned: bool) -> None:
    assert is_aligned(ego, partner) is aligned


def test_start_states_are_paired_by_seed() -> None:
    a, b, c = start_states(7, 20, 2), start_states(7, 20, 2), start_states(8, 20, 2)
    assert a.shape == (20, 2, 4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.all(a[..., 2:] == 0) and np.all((a[..., :2] >= 0) & (a[..., :2] <= 1))
    with pytest.raises(ValueError, match="n_agents"):
        start_states(0, 3, 6)


def test_sample_goal_pairs() -> None:
    pairs = sample_goal_pairs(0, 300)
    assert len(pairs) == len({(e, p) for e, p, _ in pairs}) == 300
    assert all(e in GOAL_IDS and p in GOAL_IDS and a == is_aligned(e, p) for e, p, a in pairs)
    assert any(a for *_, a in pairs) and not all(a for *_, a in pairs)
    assert sample_goal_pairs(0, 10) == sample_goal_pairs(0, 10)
    assert len(sample_goal_pairs(1, 1225)) == 1225
    with pytest.raises(ValueError, match="k"):
        sample_goal_pairs(0, 1226)


def test_scripted_controller_reaches_and_stays_in_every_target() -> None:
    episodes = 40
    goals_B1 = np.repeat(np.arange(35), episodes)[:, None]
    state = random_states(np.random.default_rng(0), goals_B1.shape[0], 1)
    reached = np.zeros(goals_B1.shape[0], dtype=bool)
    for _ in range(60):  # the slowest start needs < 30 steps
        state = step_state(state, scripted_actions(state, goals_B1))
        reached |= in_target(state, goals_B1)[:, 0]
    assert reached.all()
    assert in_target(state, goals_B1).all()  # and it stays there, at rest
    assert np.abs(state[..., 2:]).max() < 1e-3


def test_scripted_actions_point_at_the_target() -> None:
    # at rest in the centre: heading for a4 (up-left) pushes up or left; for e the push is right
    state = np.array([[[0.5, 0.5, 0, 0], [0.5, 0.5, 0, 0], [0.5, 0.5, 0, 0]]])
    acts = scripted_actions(state, np.array([[GOAL_IDS.index("a4"), GOAL_IDS.index("e"), 32]]))
    assert acts[0, 0] in (1, 3) and acts[0, 1] == 4 and acts[0, 2] == 0  # 32 = row 2: already in
