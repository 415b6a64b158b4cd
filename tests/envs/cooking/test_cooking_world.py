"""The rules, one hand-built kitchen per rule: moves and collisions, pick up, put down, chop,
blend, plating, scooping, delivery and its crediting, rewards, recipe progress."""

import numpy as np
import pytest

from envs.cooking.batched import BatchedCookingWorld
from envs.cooking.layouts import parse_layout
from envs.cooking.recipes import BLENDED, CHOPPED, RAW
from envs.cooking.world import CookingState, recipe_progress

STAY, UP, DOWN, LEFT, RIGHT = range(5)


def world(text: str, *recipes: str, **kwargs: float) -> BatchedCookingWorld:
    return BatchedCookingWorld(parse_layout(text), np.array([recipes]), **kwargs)  # type: ignore[arg-type]


def act(w: BatchedCookingWorld, *actions: int) -> np.ndarray:
    """Step the single kitchen; returns the rewards of this step."""
    return w.step(np.array([actions])).rewards_BN[0]


def agents(w: BatchedCookingWorld) -> list[list[int]]:
    return w.state.agent_rc[0].tolist()


@pytest.mark.parametrize(
    ("text", "actions", "expected"),
    [
        ("#0.1#", (RIGHT, LEFT), [[0, 1], [0, 3]]),  # both into the same cell: neither moves
        ("#01#", (RIGHT, LEFT), [[0, 1], [0, 2]]),  # a swap: neither moves
        ("#01.#", (RIGHT, RIGHT), [[0, 1], [0, 3]]),  # following: the cell was taken at the start
        ("#0.#", (UP,), [[0, 1]]),  # off the grid counts as a wall
        ("#0.1#", (RIGHT, STAY), [[0, 2], [0, 3]]),
        ("#0#1.#", (RIGHT, RIGHT), [[0, 1], [0, 4]]),  # a wall: nothing happens
    ],
)
def test_moves_and_collisions(
    text: str, actions: tuple[int, ...], expected: list[list[int]]
) -> None:
    recipes = ["ChoppedTomato"] * len(actions)
    w = world(text, *recipes)
    act(w, *actions)
    assert agents(w) == expected


def test_pick_put_chop_and_pick_chopped() -> None:
    w = world("#t/#\n#0.#", "ChoppedTomato")
    act(w, UP)  # pick the tomato off the counter
    assert w.state.obj_holder[0].tolist() == [0]
    act(w, RIGHT)
    assert w.state.obj_rc[0].tolist() == [[1, 2]]  # carried along
    act(w, UP)  # put it on the board
    assert w.state.obj_holder[0].tolist() == [-1] and w.state.obj_rc[0].tolist() == [[0, 2]]
    act(w, UP)  # walking into a board with a raw ingredient chops it, once is enough
    assert w.state.obj_state[0].tolist() == [CHOPPED] and w.state.obj_holder[0].tolist() == [-1]
    act(w, UP)  # now it is picked up
    assert w.state.obj_holder[0].tolist() == [0]
    act(w, LEFT)
    act(w, UP)  # ... and put back on the (now empty) counter
    assert w.state.obj_rc[0].tolist() == [[0, 1]] and w.state.obj_holder[0].tolist() == [-1]


def test_blender_and_station_restrictions() -> None:
    w = world("#oBp#\n#.0.#", "OnionSoup")
    act(w, LEFT)
    act(w, UP)  # pick the onion
    act(w, RIGHT)
    act(w, UP)  # into the blender
    act(w, UP)  # blend
    assert w.state.obj_state[0].tolist() == [BLENDED, RAW]
    act(w, UP)  # pick the blended onion
    act(w, RIGHT)
    act(w, UP)  # put it onto the plate
    assert w.state.obj_plate[0].tolist() == [1, -1]
    act(w, UP)  # pick up the plate with its contents
    act(w, LEFT)
    act(w, UP)  # a plate is not accepted by the blender
    assert w.state.obj_holder[0].tolist() == [-1, 0]
    assert w.state.obj_rc[0].tolist() == [[1, 2], [1, 2]]  # contents follow the plate


def test_scoop_with_a_plate_and_nothing_off_a_plate() -> None:
    w = world("#t/p#\n#..0#", "ChoppedTomato")
    act(w, UP)  # pick the plate
    act(w, LEFT)
    act(w, LEFT)
    act(w, UP)  # a held plate scoops the raw tomato off its counter
    assert w.state.obj_plate[0].tolist() == [1, -1]
    act(w, RIGHT)
    act(w, UP)  # a plate is not accepted by a board: nothing happens
    assert w.state.obj_holder[0].tolist() == [-1, 0]
    act(w, LEFT)
    act(w, UP)  # put the plate down on a counter
    act(w, UP)  # picks the whole plate up again: nothing comes off a plate
    assert w.state.obj_holder[0].tolist() == [-1, 0] and w.state.obj_plate[0].tolist() == [1, -1]


def test_two_agents_interacting_with_one_cell_both_fail() -> None:
    w = world("#0t1#", "ChoppedTomato", "ChoppedTomato")
    act(w, RIGHT, LEFT)
    assert w.state.obj_holder[0].tolist() == [-1]
    act(w, RIGHT, STAY)
    assert w.state.obj_holder[0].tolist() == [0]


def _plated_state(w: BatchedCookingWorld, holder: int, tomato_state: int) -> CookingState:
    """The layout "#pt*#" with the tomato (object 1) on the plate (object 0) held by `holder`."""
    s = w.state
    s.obj_holder[0, 0] = holder
    s.obj_plate[0, 1] = 0
    s.obj_state[0, 1] = tomato_state
    return s


DELIVERY_KITCHEN = "#pt*#\n#0.1#"


def test_delivery_credits_the_partner_and_rewards() -> None:
    w = world(DELIVERY_KITCHEN, "CarrotBanana", "ChoppedTomato")
    w.reset(_plated_state(w, holder=1, tomato_state=CHOPPED))  # agent 1 under the delivery square
    rewards = act(w, STAY, UP)
    assert rewards.tolist() == pytest.approx([-0.01, 19.99])
    assert w.state.delivered[0].tolist() == [False, True]
    assert w.state.obj_gone[0].tolist() == [True, True]
    assert act(w, STAY, STAY).tolist() == pytest.approx([-0.01, 0.0])  # no penalty once served

    w = world(DELIVERY_KITCHEN, "ChoppedTomato", "CarrotBanana")
    w.reset(_plated_state(w, holder=1, tomato_state=CHOPPED))
    rewards = act(w, STAY, UP)  # agent 1 delivers agent 0's dish: agent 0 is credited
    assert rewards.tolist() == pytest.approx([19.99, -0.01])
    assert w.state.delivered[0].tolist() == [True, False]


def test_deliverer_first_and_refused_dishes() -> None:
    w = world(DELIVERY_KITCHEN, "ChoppedTomato", "ChoppedTomato")
    w.reset(_plated_state(w, holder=1, tomato_state=CHOPPED))
    act(w, STAY, UP)
    assert w.state.delivered[0].tolist() == [False, True]

    w = world(DELIVERY_KITCHEN, "ChoppedTomato", "ChoppedTomato")
    w.reset(_plated_state(w, holder=1, tomato_state=RAW))  # a raw tomato is no dish
    rewards = act(w, STAY, UP)
    assert rewards.tolist() == pytest.approx([-0.01, -0.01])
    assert w.state.obj_holder[0].tolist() == [1, -1] and not w.state.obj_gone.any()


def test_termination_and_truncation() -> None:
    w = world(DELIVERY_KITCHEN, "ChoppedTomato", "ChoppedTomato", max_steps=3)
    s = _plated_state(w, holder=1, tomato_state=CHOPPED)
    s.delivered[0, 0] = True
    w.reset(s)
    result = w.step(np.array([[STAY, UP]]))
    assert result.terminated_B.tolist() == [True] and result.truncated_B.tolist() == [False]
    w.reset()
    results = [w.step(np.array([[STAY, STAY]])) for _ in range(3)]
    assert [bool(r.truncated_B[0]) for r in results] == [False, False, True]
    assert not any(r.terminated_B[0] for r in results)


def test_recipe_progress_and_sub_goal_rewards() -> None:
    text = "#t/p*#\n#0...#"
    w = world(text, "ChoppedTomato", sub_goal_reward=1.0)
    progress = recipe_progress(w.layout, w.state, w.recipes)
    assert progress.count_BN.tolist() == [[0]]
    rewards = [act(w, a)[0] for a in (UP, RIGHT, UP, UP)]  # pick, move, put on board, chop
    assert rewards == pytest.approx([-0.01, -0.01, -0.01, 0.99])  # "prepare" done
    progress = recipe_progress(w.layout, w.state, w.recipes)
    assert progress.prepared_BNK[0, 0].tolist() == [True, False]  # padding stays False
    assert progress.plated_BNK[0, 0].tolist() == [False, False]
    rewards = [act(w, a)[0] for a in (UP, RIGHT, UP)]  # pick chopped, move, onto the plate
    assert rewards == pytest.approx([-0.01, -0.01, 0.99])  # "plate" done
    rewards = [act(w, a)[0] for a in (UP, RIGHT, UP)]  # pick plate, move, deliver
    assert rewards == pytest.approx([-0.01, -0.01, 19.99])
    assert recipe_progress(w.layout, w.state, w.recipes).delivered_BN.tolist() == [[True]]


def test_sub_goals_are_paid_once() -> None:
    """Agent 0 (salad) loses its chopped tomato when agent 1 delivers it as its own dish; chopping
    the second tomato restores a step already paid for, so it earns nothing."""
    w = world("#pt*t/#\n#.1..0#", "TomatoLettuceSalad", "ChoppedTomato", sub_goal_reward=0.5)
    w.reset(_plated_state(w, holder=1, tomato_state=CHOPPED))  # baseline: prepared + plated
    assert recipe_progress(w.layout, w.state, w.recipes).count_BN.tolist() == [[2, 2]]
    assert act(w, STAY, RIGHT).tolist() == pytest.approx([-0.01, -0.01])
    assert act(w, STAY, UP).tolist() == pytest.approx([-0.01, 19.99])  # agent 1 served
    assert recipe_progress(w.layout, w.state, w.recipes).count_BN[0, 0] == 0
    rewards = [act(w, a, STAY)[0] for a in (LEFT, UP, RIGHT, UP, UP)]  # fetch, board, chop
    assert w.state.obj_state[0, 2] == CHOPPED
    assert rewards == pytest.approx([-0.01] * 5)
