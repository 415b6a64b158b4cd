"""A kitchen as a `envs.scene.Scene` (the web console draws it; `render.py` draws pixels).

| element         | shape                                                              |
|-----------------|--------------------------------------------------------------------|
| floor / wall    | light / dark square per cell                                       |
| counter         | tan square                                                         |
| station         | counter with a word: "board" (cutting board), "blend", "serve"     |
| ingredient      | disc in its colour (raw), three small discs (chopped), a square    |
|                 | (blended); at its cell, on its plate, or small beside its holder   |
| plate           | white disc with a grey rim                                         |
| agent           | `AgentMark` at its cell's centre; what it holds drawn beside it    |

Units are cells: x = column, y = row, y down; a cell's centre is (column + 0.5, row + 0.5).
Colours are `render.py`'s, so the console and the GIFs agree.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from envs.cooking.layouts import BLENDER, BOARD, COUNTER, DELIVERY, FLOOR, WALL, Layout
from envs.cooking.recipes import BLENDED, CHOPPED, INGREDIENTS, PLATE, STATE_NAMES
from envs.cooking.render import AGENT_COLOURS, CELL_COLOURS, FLOOR_COLOUR, INGREDIENT_COLOURS
from envs.cooking.world import CookingState
from envs.scene import AgentMark, Scene, SceneFrame, Shape, circle, hex_colour, rect, text

AGENT_RADIUS = 0.36  # of a cell, as in the GIFs
STATION_WORDS = {BOARD: "board", BLENDER: "blend", DELIVERY: "serve"}
CELL_WORDS = {
    FLOOR: "floor",
    WALL: "wall",
    COUNTER: "counter",
    BOARD: "cutting board",
    BLENDER: "blender",
    DELIVERY: "delivery square",
}
DARK = "#282828"
PLATE_FILL, PLATE_RIM = "#fafafa", "#828282"


def _check(layout: Layout, recipes: Sequence[str]) -> None:
    if len(recipes) != layout.n_agents:
        raise ValueError(
            f"recipes: expected {layout.n_agents} (one per agent of {layout.name!r}), "
            f"got {len(recipes)}"
        )


def cooking_scene(layout: Layout, recipes: Sequence[str]) -> Scene:
    """Every cell of `layout` (agent i cooks `recipes[i]`)."""
    _check(layout, recipes)
    height, width = layout.shape
    shapes: list[Shape] = []
    for r in range(height):
        for c in range(width):
            kind = int(layout.cells_HW[r, c])
            fill = hex_colour(CELL_COLOURS.get(kind, FLOOR_COLOUR))
            where = f"row {r}, column {c}"
            shapes.append(
                rect(
                    c,
                    r,
                    1.0,
                    1.0,
                    fill=fill,
                    stroke="#aaa096",
                    label=f"{CELL_WORDS[kind]} at {where}",
                )
            )
            if kind in STATION_WORDS:
                shapes.append(
                    text(
                        c + 0.5,
                        r + 0.5,
                        STATION_WORDS[kind],
                        0.26,
                        fill=DARK,
                        label=f"{CELL_WORDS[kind]} at {where}",
                    )
                )
    colours = tuple(hex_colour(col) for col in AGENT_COLOURS[: layout.n_agents])
    return Scene(float(width), float(height), False, AGENT_RADIUS, colours, tuple(shapes))


def _name(layout: Layout, state: CookingState, o: int) -> str:
    kind = int(layout.object_kinds_O[o])
    if kind == PLATE:
        return f"plate {o}"
    return f"{STATE_NAMES[int(state.obj_state[0, o])]} {INGREDIENTS[kind]}"


def _ingredient(x: float, y: float, r: float, kind: int, state: int, label: str) -> list[Shape]:
    colour = hex_colour(INGREDIENT_COLOURS[kind])
    if state == CHOPPED:
        s = r * 0.5
        return [
            circle(x + dx * r, y + dy * r, s, fill=colour, stroke=DARK, label=label)
            for dx, dy in ((-0.6, 0.3), (0.6, 0.3), (0.0, -0.5))
        ]
    if state == BLENDED:
        return [rect(x - r, y - r, 2 * r, 2 * r, fill=colour, stroke=DARK, label=label)]
    return [circle(x, y, r, fill=colour, stroke=DARK, label=label)]


def _object(
    layout: Layout, state: CookingState, o: int, x: float, y: float, r: float, where: str
) -> list[Shape]:
    """Object o centred at (x, y): a lone ingredient, or a plate with what lies on it."""
    kind = int(layout.object_kinds_O[o])
    if kind != PLATE:
        label = f"{_name(layout, state, o)} {where}"
        return _ingredient(x, y, r, kind, int(state.obj_state[0, o]), label)
    on_plate = np.flatnonzero((state.obj_plate[0] == o) & ~state.obj_gone[0]).tolist()
    contents = ", ".join(_name(layout, state, k) for k in on_plate) or "nothing"
    shapes = [
        circle(x, y, r, fill=PLATE_FILL, stroke=PLATE_RIM, label=f"plate {where} with {contents}")
    ]
    offsets = ((-0.35, 0.0), (0.35, 0.0), (0.0, -0.35), (0.0, 0.35))
    for (dx, dy), k in zip(offsets, on_plate, strict=False):
        shapes += _ingredient(
            x + dx * r,
            y + dy * r,
            r * 0.4,
            int(layout.object_kinds_O[k]),
            int(state.obj_state[0, k]),
            f"{_name(layout, state, k)} on a plate",
        )
    return shapes


def cooking_frame(layout: Layout, state: CookingState, recipes: Sequence[str]) -> SceneFrame:
    """The agents and objects of the first kitchen of `state`."""
    _check(layout, recipes)
    if state.agent_rc.shape[1:] != (layout.n_agents, 2):
        raise ValueError(f"state: expected {layout.n_agents} agents for {layout.name!r}")
    shapes: list[Shape] = []
    lone = (state.obj_holder[0] < 0) & (state.obj_plate[0] < 0) & ~state.obj_gone[0]
    for o in np.flatnonzero(lone).tolist():
        r, c = state.obj_rc[0, o].tolist()
        shapes += _object(layout, state, o, c + 0.5, r + 0.5, 0.32, f"at row {r}, column {c}")
    marks = []
    for i, (r, c) in enumerate(state.agent_rc[0].tolist()):
        held = np.flatnonzero(state.obj_holder[0] == i).tolist()
        served = bool(state.delivered[0, i])
        holds = f"holds {_name(layout, state, held[0])}" if held else "holds nothing"
        status = "served" if served else (holds if held else "")
        label = f"agent {i} ({recipes[i]}) at row {r}, column {c}, {holds}" + (
            ", dish served" if served else ""
        )
        marks.append(AgentMark(i, c + 0.5, r + 0.5, label, status))
        if held:
            shapes += _object(layout, state, held[0], c + 0.72, r + 0.72, 0.2, f"held by agent {i}")
    return SceneFrame(tuple(marks), tuple(shapes))
