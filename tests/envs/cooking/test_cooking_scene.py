"""A kitchen as a scene: one square per cell in its kind's colour, stations labelled, agents and
objects where the state puts them (what an agent holds drawn with it), deliveries shown."""

import numpy as np
import pytest

from envs.cooking.domain import COOKING
from envs.cooking.layouts import DELIVERY, STATION_KINDS, get_layout
from envs.cooking.recipes import INGREDIENTS, PLATE
from envs.cooking.render import CELL_COLOURS, FLOOR_COLOUR
from envs.cooking.scene import cooking_frame, cooking_scene
from envs.cooking.world import start_states
from envs.registry import make_env
from envs.scene import hex_colour

RECIPES = ("TomatoLettuceSalad", "CarrotBanana")


def test_every_cell_is_drawn_in_its_kinds_colour_and_stations_are_named() -> None:
    layout = get_layout("coexistence")
    scene = cooking_scene(layout, RECIPES)
    height, width = layout.shape
    assert (scene.width, scene.height, scene.y_up) == (width, height, False)
    cells = [s for s in scene.shapes if s.kind == "rect"]
    assert len(cells) == height * width
    for cell in cells:
        kind = int(layout.cells_HW[int(cell.y), int(cell.x)])
        assert cell.fill == hex_colour(CELL_COLOURS.get(kind, FLOOR_COLOUR))
    words = [s for s in scene.shapes if s.kind == "text"]
    assert len(words) == sum(len(layout.stations[k]) for k in STATION_KINDS)
    delivery = {(int(r), int(c)) for r, c in layout.stations[DELIVERY]}
    served = {(int(s.y - 0.5), int(s.x - 0.5)) for s in words if s.text == "serve"}
    assert served == delivery


def test_agents_and_objects_stand_where_the_state_puts_them() -> None:
    env = make_env("cooking", RECIPES)
    env.reset(seed=0)
    frame = COOKING.scene_frame(env)
    layout = env.layout
    for mark, (r, c) in zip(frame.agents, layout.agent_starts_N2.tolist(), strict=True):
        assert (mark.x, mark.y) == (c + 0.5, r + 0.5)
        assert "holds nothing" in mark.label and mark.status == ""
    # every object lies on its counter at the start: plates as discs, ingredients as discs
    assert len(frame.shapes) == layout.n_objects
    for shape, (r, c) in zip(frame.shapes, layout.object_starts_O2.tolist(), strict=True):
        assert (shape.kind, shape.x, shape.y) == ("circle", c + 0.5, r + 0.5)


def test_what_an_agent_holds_goes_with_it_and_a_served_dish_is_shown() -> None:
    layout = get_layout("coexistence")
    state = start_states(layout, 1)
    tomato = int(np.flatnonzero(layout.object_kinds_O == INGREDIENTS.index("tomato"))[0])
    plate = int(np.flatnonzero(layout.object_kinds_O == PLATE)[0])
    state.obj_holder[0, plate] = 0  # agent 0 carries a plate with a chopped tomato on it
    state.obj_rc[0, plate] = state.agent_rc[0, 0]
    state.obj_plate[0, tomato], state.obj_state[0, tomato] = plate, 1
    state.delivered[0, 1] = True
    frame = cooking_frame(layout, state, RECIPES)
    assert frame.agents[0].status == f"holds plate {plate}"
    assert frame.agents[1].status == "served" and "dish served" in frame.agents[1].label
    held = [s for s in frame.shapes if "held by agent 0" in s.label]
    assert len(held) == 1 and "with chopped tomato" in held[0].label
    r, c = state.agent_rc[0, 0].tolist()
    assert c < held[0].x < c + 1 and r < held[0].y < r + 1  # drawn on the agent's cell
    assert any(s.label == "chopped tomato on a plate" for s in frame.shapes)


def test_bad_input_is_refused() -> None:
    layout = get_layout("coexistence")
    with pytest.raises(ValueError, match="recipes"):
        cooking_scene(layout, RECIPES[:1])
    with pytest.raises(TypeError, match="kitchen"):
        COOKING.scene_frame(make_env("particle", ("a2",)))
