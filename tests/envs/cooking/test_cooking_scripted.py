"""Scripted cooks prove every recipe completable and the coexistence situation real: the right
cook cannot serve CarrotBanana without the left cook's carrot, and can with the hand-over."""

import numpy as np
import pytest

from envs.cooking.batched import BatchedCookingWorld
from envs.cooking.layouts import get_layout
from envs.cooking.navigation import STAY, action_towards
from envs.cooking.recipes import RECIPE_NAMES
from envs.cooking.scripted import ScriptedCook, scripted_actions
from envs.cooking.world import DISH_REWARD, TIME_PENALTY


def run(
    layout: str, recipes: tuple[str, ...], cooks: list[ScriptedCook | None], max_steps: int = 400
) -> tuple[list[int | None], np.ndarray]:
    """Steps at which each agent's dish was served (None: never) and the returns."""
    world = BatchedCookingWorld(layout, np.array([recipes]), max_steps=max_steps)
    world.reset()
    served: list[int | None] = [None] * len(recipes)
    returns = np.zeros(len(recipes))
    for t in range(1, max_steps + 1):
        result = world.step(scripted_actions(world.layout, world.state, cooks))
        returns += result.rewards_BN[0]
        for i, done in enumerate(world.state.delivered[0].tolist()):
            if done and served[i] is None:
                served[i] = t
        if result.terminated_B[0]:
            break
    return served, returns


# Steps the planner needs with the partner standing still (documented in the report).
OPEN_STEPS = {
    "ChoppedTomato": 19,
    "TomatoLettuceSalad": 28,
    "CarrotBanana": 48,
    "OnionSoup": 34,
    "BananaSmoothie": 25,
}


@pytest.mark.parametrize("recipe", RECIPE_NAMES)
def test_every_recipe_is_completed_in_the_open_kitchen(recipe: str) -> None:
    served, returns = run("open", (recipe, "ChoppedTomato"), [ScriptedCook(recipe), None])
    assert served[0] == OPEN_STEPS[recipe]
    assert returns[0] == pytest.approx(DISH_REWARD - TIME_PENALTY * served[0])
    assert served[1] is None  # nobody cooks for the idle partner


def test_two_cooks_share_the_open_kitchen() -> None:
    served, _ = run(
        "open",
        ("OnionSoup", "TomatoLettuceSalad"),
        [ScriptedCook("OnionSoup"), ScriptedCook("TomatoLettuceSalad")],
    )
    assert all(t is not None and t < 100 for t in served)


def test_coexistence_needs_the_carrot_handover() -> None:
    recipes = ("TomatoLettuceSalad", "CarrotBanana")
    left, right = ScriptedCook(recipes[0]), ScriptedCook(recipes[1])
    # the left recipe needs no help
    served, _ = run("coexistence", recipes, [left, None])
    assert served == [25, None]
    # without the hand-over the right cook never serves, whatever it does for 400 steps
    served, returns = run("coexistence", recipes, [left, right])
    assert served == [25, None]
    assert returns[1] == pytest.approx(-400 * TIME_PENALTY)
    # with it, both serve: after the left dish (as AAIL did in the paper) or before it
    helper = ScriptedCook(recipes[0], handover="carrot")
    assert run("coexistence", recipes, [helper, right])[0] == [25, 52]
    helper_first = ScriptedCook(recipes[0], handover="carrot", handover_first=True)
    assert run("coexistence", recipes, [helper_first, right])[0] == [29, 28]


def test_a_cook_can_prepare_the_handed_over_ingredient_first() -> None:
    recipes = ("TomatoLettuceSalad", "CarrotBanana")
    helper_first = ScriptedCook(recipes[0], handover="carrot", handover_first=True)
    waiter = ScriptedCook(recipes[1], first="carrot")
    world = BatchedCookingWorld("coexistence", np.array([recipes]))
    assert waiter.target(world.layout, world.state, 0, 1) is None  # no carrot in reach: wait
    assert ScriptedCook(recipes[1]).target(world.layout, world.state, 0, 1) == (0, 8)  # banana
    served, _ = run("coexistence", recipes, [helper_first, waiter])
    assert served[0] == 29 and served[1] is not None and served[1] > 28  # later, but served
    # with no carrot to wait for (nobody hands it over) the waiter never touches its banana
    world = BatchedCookingWorld("coexistence", np.array([recipes]), max_steps=60)
    for _ in range(60):
        world.step(scripted_actions(world.layout, world.state, [None, waiter]))
    banana = int(np.flatnonzero(world.layout.object_kinds_O == 4)[0])
    assert world.state.obj_holder[0, banana] == -1 and world.state.obj_state[0, banana] == 0


def test_a_cook_walks_round_others_or_waits() -> None:
    layout = get_layout("###=#\n=0..#\n#.#.#\n#...#\n#####")
    # the short way to the counter at (0, 3) is blocked at (1, 2): down and round the pillar
    assert action_towards(layout, (1, 1), (0, 3), blocked={(1, 2)}) == 2
    assert action_towards(layout, (1, 1), (0, 3), blocked=set()) == 4
    assert action_towards(layout, (1, 1), (0, 3), blocked={(1, 2), (2, 1)}) == STAY  # shut in
    assert action_towards(layout, (1, 1), (1, 0), blocked=set()) == 3  # next to it: walk in


def test_bad_cooks() -> None:
    with pytest.raises(ValueError, match="Pizza"):
        ScriptedCook("Pizza")
    with pytest.raises(ValueError, match="handover"):
        ScriptedCook("ChoppedTomato", handover="steak")
    with pytest.raises(ValueError, match="first: expected one of"):
        ScriptedCook("ChoppedTomato", first="steak")
    world = BatchedCookingWorld("open", np.array([["ChoppedTomato"] * 2]))
    with pytest.raises(ValueError, match="cooks"):
        scripted_actions(world.layout, world.state, [None])
