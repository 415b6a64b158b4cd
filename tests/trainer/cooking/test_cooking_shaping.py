"""Training shaping and curriculum of the kitchen: wasted ingredients, the spoil penalty, and
scripted starts that hold both orders of CarrotBanana."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from envs.cooking import BatchedCookingWorld, CookingState
from envs.cooking.recipes import CHOPPED, RAW
from trainer.cooking.config import CookingTaskConfig
from trainer.cooking.kitchens import Kitchens
from trainer.cooking.shaping import wasted_items

FIG8 = np.array([["TomatoLettuceSalad", "CarrotBanana"]])
TOMATO, CARROT, BANANA, PLATE = 0, 3, 4, 5


def _objects(world: BatchedCookingWorld) -> dict[str, int]:
    kinds = world.layout.object_kinds_O
    plates = np.flatnonzero(kinds == PLATE)  # reading order: the right room's (1, 10) first
    return {
        "tomato": int(np.flatnonzero(kinds == TOMATO)[0]),
        "carrot": int(np.flatnonzero(kinds == CARROT)[0]),
        "banana": int(np.flatnonzero(kinds == BANANA)[0]),
        "right_plate": int(plates[0]),
    }


def _plated(on_plate: dict[str, int]) -> tuple[BatchedCookingWorld, CookingState]:
    """The coexistence kitchen with the given ingredients (name -> state) on the right plate."""
    world = BatchedCookingWorld("coexistence", FIG8)
    obj = _objects(world)
    state = world.state
    assert tuple(state.obj_rc[0, obj["right_plate"]]) == (1, 10)
    for name, item_state in on_plate.items():
        state.obj_plate[0, obj[name]] = obj["right_plate"]
        state.obj_state[0, obj[name]] = item_state
    world.reset(state)  # checks the state and moves plated items onto their plate
    return world, world.state


@pytest.mark.parametrize(
    ("on_plate", "wasted"),
    [
        ({}, [0, 0]),
        ({"carrot": CHOPPED}, [0, 0]),  # a good start on CarrotBanana
        ({"carrot": CHOPPED, "banana": RAW}, [0, 2]),  # raw banana: neither can be served
        ({"carrot": RAW}, [0, 1]),  # a raw carrot on a plate is never chopped
        ({"carrot": CHOPPED, "tomato": CHOPPED}, [1, 1]),  # each spoils the other's dish
    ],
)
def test_wasted_items(on_plate: dict[str, int], wasted: list[int]) -> None:
    world, state = _plated(on_plate)
    np.testing.assert_array_equal(wasted_items(world.layout, state, world.recipes), [wasted])


def _spoil_step(penalty: float) -> tuple[float, float]:
    """The right cook, holding the plate with a chopped carrot, walks into the raw banana."""
    cfg = replace(CookingTaskConfig(), spoil_penalty=penalty)
    kitchens = Kitchens("CarrotBanana", 1, cfg, 0, auto_reset=False, scripted_starts=False)
    world, state = _plated({"carrot": CHOPPED})
    obj = _objects(world)
    state.agent_rc[0, 1] = (1, 8)  # the banana lies above, at (0, 8)
    state.obj_holder[0, obj["right_plate"]] = 1
    kitchens.start_from(state)
    out = kitchens.step(np.array([[0, 1]]))  # left cook stays, right cook: up
    assert kitchens.world.state.obj_plate[0, obj["banana"]] == obj["right_plate"]  # scooped
    return float(out.rewards_BN[0, 1]), float(out.unshaped_BN[0, 1])


def test_the_spoiling_step_is_penalised_in_training_only() -> None:
    shaped, unshaped = _spoil_step(penalty=2.0)
    assert unshaped == pytest.approx(-0.01)
    assert shaped == pytest.approx(-0.01 - 2.0 * 2)  # two wasted items: carrot and banana
    assert _spoil_step(penalty=0.0)[0] == pytest.approx(-0.01)


def _carrot_first_states(other_order_prob: float) -> int:
    cfg = replace(
        CookingTaskConfig(),
        pool_other_order_prob=other_order_prob,
        pool_episodes=6,
        pool_idle_max=0,
    )
    pool = Kitchens("CarrotBanana", 1, cfg, 3).pool
    assert pool is not None
    obj = _objects(BatchedCookingWorld("coexistence", FIG8))
    states = pool.states.obj_state
    return int(np.sum((states[:, obj["carrot"]] == CHOPPED) & (states[:, obj["banana"]] == RAW)))


def test_scripted_starts_hold_both_orders_of_the_recipe() -> None:
    assert _carrot_first_states(0.0) == 0  # the planner always chops the banana first
    assert _carrot_first_states(1.0) > 10  # it waits for the carrot and chops it first
