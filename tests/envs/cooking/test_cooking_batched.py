"""The batched simulator: shapes, independence of kitchens, equality with the PettingZoo env step
for step, reset_where, set_goals, random starts, determinism and bad input."""

import numpy as np
import pytest

from envs.cooking.batched import BatchedCookingWorld
from envs.cooking.env import CookingEnv
from envs.cooking.layouts import get_layout
from envs.cooking.recipes import RECIPE_NAMES, recipe_indices
from envs.cooking.world import start_states

RECIPES = ("TomatoLettuceSalad", "CarrotBanana")


def test_shapes_and_names_or_indices() -> None:
    world = BatchedCookingWorld("open", np.array([RECIPES] * 4), seed=0)
    obs = world.reset()
    assert obs.shape == (4, 2, 188) and obs.dtype == np.float32
    assert world.recipes.tolist() == [[1, 2]] * 4 and world.recipe_names(3) == RECIPES
    result = world.step(np.zeros((4, 2), dtype=np.int64))
    assert result.rewards_BN.shape == (4, 2) and result.terminated_B.shape == (4,)
    assert world.steps.tolist() == [1] * 4
    same = BatchedCookingWorld("open", recipe_indices(np.array([RECIPES] * 4)), seed=0)
    np.testing.assert_array_equal(same.reset(), obs)


def test_kitchens_are_independent_and_equal_the_pettingzoo_env() -> None:
    """Kitchen b of a batch follows exactly the PettingZoo env fed the same actions."""
    rng = np.random.default_rng(0)
    n_envs, steps = 3, 300
    actions_TBN = rng.integers(0, 5, size=(steps, n_envs, 2))
    batch = BatchedCookingWorld("open", np.array([RECIPES] * n_envs), max_steps=400)
    batch.reset()
    envs = [CookingEnv(layout="open", recipes=RECIPES) for _ in range(n_envs)]
    for env in envs:
        env.reset(seed=1)
    for t in range(steps):
        result = batch.step(actions_TBN[t])
        for b, env in enumerate(envs):
            obs, rewards, term, trunc, _ = env.step(
                {"agent_0": int(actions_TBN[t, b, 0]), "agent_1": int(actions_TBN[t, b, 1])}
            )
            np.testing.assert_array_equal(obs["agent_0"], result.next_obs_BND[b, 0])
            np.testing.assert_array_equal(obs["agent_1"], result.next_obs_BND[b, 1])
            assert [rewards["agent_0"], rewards["agent_1"]] == result.rewards_BN[b].tolist()
            assert term["agent_0"] == result.terminated_B[b] and not trunc["agent_0"]
    state = batch.state
    assert any(  # the random walks did move objects around
        not np.array_equal(state.obj_rc[b], get_layout("open").object_starts_O2)
        for b in range(n_envs)
    )


def test_reset_where_and_set_goals() -> None:
    world = BatchedCookingWorld("coexistence", np.array([RECIPES] * 3), seed=0)
    world.reset()
    for _ in range(5):
        world.step(np.full((3, 2), 1))
    moved = world.state.agent_rc.copy()
    obs = world.reset_where(np.array([False, True, False]))
    start = start_states(world.layout, 1)
    assert world.state.agent_rc[1].tolist() == start.agent_rc[0].tolist()
    np.testing.assert_array_equal(world.state.agent_rc[[0, 2]], moved[[0, 2]])
    assert world.steps.tolist() == [5, 0, 5]
    np.testing.assert_array_equal(obs, world.observe())
    np.testing.assert_array_equal(world.reset_where(np.zeros(3, dtype=bool)), obs)
    world.set_goals(np.array([["ChoppedTomato", "CarrotBanana"]] * 3))
    assert world.recipes[:, 0].tolist() == [RECIPE_NAMES.index("ChoppedTomato")] * 3


def test_random_starts_stay_in_each_agents_area_and_are_seeded() -> None:
    def starts(seed: int) -> np.ndarray:
        world = BatchedCookingWorld(
            "coexistence", np.array([RECIPES] * 64), seed=seed, random_starts=True
        )
        return world.state.agent_rc

    a, b = starts(1), starts(1)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, starts(2))
    assert np.all(a[:, 0, 1] <= 4) and np.all(a[:, 1, 1] >= 6)  # left room / right room
    assert len({tuple(rc) for rc in a[:, 0].tolist()}) > 5


def test_bad_input() -> None:
    with pytest.raises(ValueError, match="recipes_BN"):
        BatchedCookingWorld("open", np.array([["ChoppedTomato"]]))
    with pytest.raises(ValueError, match="Pizza"):
        BatchedCookingWorld("open", np.array([["Pizza", "ChoppedTomato"]]))
    with pytest.raises(ValueError, match="max_steps"):
        BatchedCookingWorld("open", np.array([RECIPES]), max_steps=0)
    with pytest.raises(ValueError, match="sub_goal_reward"):
        BatchedCookingWorld("open", np.array([RECIPES]), sub_goal_reward=float("nan"))
    world = BatchedCookingWorld("open", np.array([RECIPES] * 2))
    with pytest.raises(ValueError, match="actions_BN"):
        world.step(np.zeros((2, 3), dtype=np.int64))
    with pytest.raises(ValueError, match="actions_BN"):
        world.step(np.full((2, 2), 5))
    with pytest.raises(ValueError, match="actions_BN"):
        world.step(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="mask_B"):
        world.reset_where(np.ones(3, dtype=bool))
    with pytest.raises(ValueError, match="recipes_BN"):
        world.set_goals(np.array([RECIPES]))
    bad = world.state
    bad.agent_rc[0, 1] = bad.agent_rc[0, 0]
    with pytest.raises(ValueError, match="two agents"):
        world.reset(bad)
    bad = world.state
    bad.agent_rc[0, 0] = (0, 0)
    with pytest.raises(ValueError, match="floor"):
        world.reset(bad)
    bad = world.state
    bad.obj_holder[0, :2] = 0
    with pytest.raises(ValueError, match="more than one"):
        world.reset(bad)
    with pytest.raises(ValueError, match="shape"):
        world.reset(start_states(world.layout, 3))
