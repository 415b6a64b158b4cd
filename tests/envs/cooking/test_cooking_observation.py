"""Observations: one length for every layout, hand-computed features, the perspective transform
(exact, round trip) and the domain's views."""

from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from envs.base import Domain
from envs.cooking.batched import BatchedCookingWorld
from envs.cooking.domain import COOKING
from envs.cooking.layouts import BUILTIN_LAYOUTS, get_layout, parse_layout
from envs.cooking.observation import (
    feature_names,
    from_perspective,
    observation_bounds,
    perspective,
)

THREE_COOKS = """
#t=l=o=c=b#
p.0.....1.=
/...2.....*
#p=B=*=/=p#
"""


def _obs_after(layout: str, recipes: list[str], actions_TN: np.ndarray) -> np.ndarray:
    w = BatchedCookingWorld(layout, np.array([recipes]))
    obs = w.reset()
    for a in actions_TN:
        obs = w.step(a[None]).next_obs_BND
    return obs[0]


def test_same_length_for_every_layout() -> None:
    assert COOKING.obs_dim(2) == COOKING.pair_obs_dim == 188
    assert [COOKING.obs_dim(n) for n in (1, 3, 4)] == [176, 200, 212]
    for name in BUILTIN_LAYOUTS:
        obs = _obs_after(name, ["ChoppedTomato"] * 2, np.zeros((0, 2), dtype=np.int64))
        assert obs.shape == (2, 188) and obs.dtype == np.float32
    assert len(COOKING.observation_layout(3)) == 200 and len(set(feature_names(3))) == 200


def test_hand_computed_features() -> None:
    names = feature_names(2)
    at = {n: i for i, n in enumerate(names)}
    # coexistence: agent 0 at (row 2, col 2), agent 1 at (2, 8); tomato at (0, 1)
    obs = _obs_after("coexistence", ["TomatoLettuceSalad", "CarrotBanana"], np.array([[1, 0]]))
    ego, partner = obs  # agent 0 moved up to (1, 2)
    assert ego[at["self.x"]] == 2 / 16 and ego[at["self.y"]] == 1 / 16
    assert ego[at["other1.x"]] == 8 / 16 and ego[at["other1.rel_x"]] == 6 / 16
    assert ego[at["tomato0.present"]] == 1 and ego[at["tomato0.rel_y"]] == -1 / 16
    assert ego[at["tomato1.present"]] == 0 and ego[at["tomato1.rel_x"]] == 0  # no 2nd tomato
    assert ego[at["plate0.x"]] == 10 / 16 and ego[at["plate1.y"]] == 4 / 16
    assert ego[at["cutting_board1.x"]] == 10 / 16 and ego[at["blender0.present"]] == 0
    assert partner[at["self.x"]] == 8 / 16 and partner[at["tomato0.rel_x"]] == -7 / 16
    # agent 0 walks left and picks up the carrot at (1, 0)
    obs = _obs_after("coexistence", ["TomatoLettuceSalad"] * 2, np.array([[1, 0], [3, 0], [3, 0]]))
    assert obs[0][at["self.holds_carrot"]] == 1 and obs[1][at["other1.holds_carrot"]] == 1
    assert obs[0][at["carrot0.held"]] == 1 and obs[0][at["carrot0.rel_x"]] == 0
    assert obs[0][at["carrot0.x"]] == 1 / 16  # the holder's cell
    low, high = observation_bounds(2)
    assert np.all(obs >= low) and np.all(obs <= high)


@settings(max_examples=25, deadline=None)
@given(
    layout=st.sampled_from(["coexistence", "open", "split", THREE_COOKS]),
    steps=st.integers(0, 150),
    seed=st.integers(0, 2**16),
)
def test_perspective_is_exact_and_invertible(layout: str, steps: int, seed: int) -> None:
    n = get_layout(layout).n_agents
    actions = np.random.default_rng(seed).integers(0, 5, size=(steps, n))  # picks, puts, chops
    obs_ND = _obs_after(layout, ["ChoppedTomato"] * n, actions)
    for j in range(n):
        view = perspective(obs_ND[0], n, j)
        np.testing.assert_array_equal(view, obs_ND[j])  # bit for bit: the env's own view
        np.testing.assert_array_equal(from_perspective(view, n, j), obs_ND[0])


def test_domain_views() -> None:
    assert isinstance(COOKING, Domain)
    assert COOKING.name == "cooking" and COOKING.n_actions == 5 and COOKING.max_agents == 4
    assert COOKING.goals[:3] == ("ChoppedTomato", "TomatoLettuceSalad", "CarrotBanana")
    rng = np.random.default_rng(3)
    two = _obs_after("open", ["OnionSoup", "CarrotBanana"], rng.integers(0, 5, size=(40, 2)))
    np.testing.assert_array_equal(COOKING.impact_view(two[:1], 2, 1)[0], two[0])
    np.testing.assert_array_equal(COOKING.partner_view(two[:1], 2, 1)[0], two[1])
    np.testing.assert_array_equal(COOKING.task_views(two[:1], 2)[:, 0], two[:1])

    three = _obs_after(THREE_COOKS, ["ChoppedTomato"] * 3, rng.integers(0, 5, size=(40, 3)))
    ego = three[:1]
    views = COOKING.task_views(ego, 3)
    assert views.shape == (1, 2, 188)
    # the (ego, other2) pair: both agents' blocks, every object, rel features relative to the ego
    pair = views[0, 1]
    np.testing.assert_array_equal(pair[:12], ego[0, :12])
    np.testing.assert_array_equal(pair[12:24], ego[0, 24:36])
    np.testing.assert_array_equal(pair[24:], ego[0, 36:])
    partner = COOKING.partner_view(ego, 3, 2)[0]
    np.testing.assert_array_equal(partner[:12], three[2, :12])  # agent 2's own block
    np.testing.assert_array_equal(partner[24:], three[2, 36:])  # objects relative to agent 2

    one = np.zeros((2, COOKING.obs_dim(1)), dtype=np.float32)
    assert COOKING.task_views(one, 1).shape == (2, 1, 188)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: COOKING.task_views(np.zeros((1, 187)), 2), "obs_BD"),
        (lambda: COOKING.impact_view(np.zeros((1, 188)), 2, 2), "partner"),
        (lambda: COOKING.partner_view(np.zeros((1, 200)), 3, 0), "partner"),
        (lambda: COOKING.obs_dim(5), "n_agents"),
        (lambda: perspective(np.zeros(188), 2, 2), "agent"),
        (lambda: perspective(np.zeros(189), 2, 1), "obs"),
    ],
)
def test_bad_views(call: Callable[[], object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        call()


def test_parse_three_cooks() -> None:
    assert parse_layout(THREE_COOKS).n_agents == 3


def test_served_feature_and_goal_reached() -> None:
    """A cook's `served` feature turns on with its dish (in its own block and, as `other1`, in
    the other cook's) and stays on; the domain reads it as the ego's final goal."""
    from envs.cooking.scripted import ScriptedCook, scripted_actions

    at = {n: i for i, n in enumerate(feature_names(2))}
    world = BatchedCookingWorld("coexistence", np.array([["TomatoLettuceSalad", "CarrotBanana"]]))
    obs = world.reset()
    cooks = [ScriptedCook("TomatoLettuceSalad"), None]
    seen: list[tuple[bool, float, float]] = []
    for _ in range(80):
        obs = world.step(scripted_actions(world.layout, world.state, cooks)).next_obs_BND
        served = bool(world.state.delivered[0, 0])
        seen.append((served, obs[0, 0, at["self.served"]], obs[0, 1, at["other1.served"]]))
        assert COOKING.goal_reached(obs[0], 2, "TomatoLettuceSalad").tolist() == [served, False]
    assert any(s for s, _, _ in seen) and not seen[0][0]  # served once, part-way
    assert all(own == other == float(s) for s, own, other in seen)
    assert COOKING.goal_is_final
