"""Drawing kitchens to RGB arrays (Pillow) and writing GIFs.

| element         | drawn as                                                               |
|-----------------|------------------------------------------------------------------------|
| floor / wall    | light beige square / dark grey square                                  |
| counter         | tan square                                                             |
| cutting board   | counter with a pale wooden board and a knife line                      |
| blender         | counter with a grey jug                                                |
| delivery square | counter with a gold star                                               |
| ingredient      | disc in its colour (raw), three small slices (chopped), a square with  |
|                 | a dark rim (blended); tomato red, lettuce green, onion violet, carrot  |
|                 | orange, banana yellow                                                  |
| plate           | white disc with a grey rim, its contents drawn small on it             |
| agent           | disc in the agent's colour with its index; what it holds drawn small   |
|                 | at its lower right                                                     |
| legend          | one line per agent under the grid: colour, recipe, "served" once done  |

Frame size: (rows × 48 + 16 × N, columns × 48, 3) uint8 with the default `cell = 48`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw

from envs.cooking.layouts import BLENDER, BOARD, COUNTER, DELIVERY, WALL, Layout
from envs.cooking.recipes import BLENDED, CHOPPED, PLATE
from envs.cooking.world import CookingState
from envs.particle.render import save_gif

__all__ = ["render_frame", "save_gif"]

AGENT_COLOURS: tuple[tuple[int, int, int], ...] = (
    (31, 119, 180),  # blue
    (230, 100, 170),  # pink (not red: tomatoes are red)
    (20, 140, 140),  # teal
    (130, 90, 50),  # brown
)
INGREDIENT_COLOURS: tuple[tuple[int, int, int], ...] = (
    (220, 40, 40),  # tomato
    (90, 185, 60),  # lettuce
    (170, 110, 190),  # onion
    (245, 140, 30),  # carrot
    (240, 215, 60),  # banana
)
CELL_COLOURS = {
    WALL: (85, 85, 90),
    COUNTER: (196, 160, 112),
    BOARD: (196, 160, 112),
    BLENDER: (196, 160, 112),
    DELIVERY: (196, 160, 112),
}
FLOOR_COLOUR = (240, 234, 222)
DARK = (40, 40, 40)
LEGEND_LINE = 16


def _ingredient(
    draw: ImageDraw.ImageDraw, cx: float, cy: float, r: float, kind: int, state: int
) -> None:
    colour = INGREDIENT_COLOURS[kind]
    if state == CHOPPED:
        s = r * 0.5
        for dx, dy in ((-0.6, 0.3), (0.6, 0.3), (0.0, -0.5)):
            x, y = cx + dx * r, cy + dy * r
            draw.ellipse((x - s, y - s, x + s, y + s), fill=colour, outline=DARK)
    elif state == BLENDED:
        draw.rounded_rectangle(
            (cx - r, cy - r, cx + r, cy + r), radius=r / 3, fill=colour, outline=DARK, width=2
        )
    else:
        draw.ellipse((cx - r, cy - r, cx + r, cy + r), fill=colour, outline=DARK)


def _object(
    draw: ImageDraw.ImageDraw,
    layout: Layout,
    state: CookingState,
    o: int,
    cx: float,
    cy: float,
    r: float,
) -> None:
    """Object o (a plate with its contents, or a lone ingredient) centred at (cx, cy)."""
    kind = int(layout.object_kinds_O[o])
    if kind != PLATE:
        _ingredient(draw, cx, cy, r, kind, int(state.obj_state[0, o]))
        return
    draw.ellipse(
        (cx - r, cy - r, cx + r, cy + r), fill=(250, 250, 250), outline=(130, 130, 130), width=2
    )
    contents = np.flatnonzero((state.obj_plate[0] == o) & ~state.obj_gone[0])
    offsets = [(-0.35, 0.0), (0.35, 0.0), (0.0, -0.35), (0.0, 0.35)]
    for (dx, dy), c in zip(offsets, contents.tolist(), strict=False):
        _ingredient(
            draw,
            cx + dx * r,
            cy + dy * r,
            r * 0.4,
            int(layout.object_kinds_O[c]),
            int(state.obj_state[0, c]),
        )


def _star(cx: float, cy: float, r: float) -> list[tuple[float, float]]:
    angles = np.pi / 2 + np.arange(10) * np.pi / 5
    radii = np.where(np.arange(10) % 2 == 0, r, r * 0.45)
    return [(cx + q * np.cos(a), cy - q * np.sin(a)) for q, a in zip(radii, angles, strict=True)]


def render_frame(
    layout: Layout, state: CookingState, recipes: Sequence[str], cell: int = 48
) -> np.ndarray:
    """One frame of the first kitchen in `state`, shape (H·cell + 16·N, W·cell, 3), uint8."""
    if cell < 12:
        raise ValueError(f"cell: expected >= 12 pixels, got {cell}")
    if len(recipes) != layout.n_agents or state.agent_rc.shape[1:] != (layout.n_agents, 2):
        raise ValueError(f"recipes/state: expected {layout.n_agents} agents for this layout")
    height, width = layout.shape
    image = Image.new("RGB", (width * cell, height * cell + LEGEND_LINE * layout.n_agents), "white")
    draw = ImageDraw.Draw(image)
    for r in range(height):
        for c in range(width):
            kind = int(layout.cells_HW[r, c])
            box = (c * cell, r * cell, (c + 1) * cell - 1, (r + 1) * cell - 1)
            draw.rectangle(box, fill=CELL_COLOURS.get(kind, FLOOR_COLOUR), outline=(170, 160, 150))
            cx, cy, q = (c + 0.5) * cell, (r + 0.5) * cell, cell * 0.5
            if kind == BOARD:
                draw.rectangle(
                    (cx - 0.8 * q, cy - 0.6 * q, cx + 0.8 * q, cy + 0.6 * q),
                    fill=(232, 204, 150),
                    outline=DARK,
                )
                draw.line(
                    (cx + 0.2 * q, cy - 0.5 * q, cx + 0.7 * q, cy - 0.1 * q),
                    fill=(150, 150, 160),
                    width=3,
                )
            elif kind == BLENDER:
                draw.rounded_rectangle(
                    (cx - 0.5 * q, cy - 0.8 * q, cx + 0.5 * q, cy + 0.8 * q),
                    radius=q / 4,
                    fill=(160, 170, 180),
                    outline=DARK,
                )
            elif kind == DELIVERY:
                draw.polygon(_star(cx, cy, 0.85 * q), fill=(250, 200, 30), outline=DARK)

    lone = np.flatnonzero((state.obj_holder[0] < 0) & (state.obj_plate[0] < 0) & ~state.obj_gone[0])
    for o in lone.tolist():
        r, c = state.obj_rc[0, o].tolist()
        _object(draw, layout, state, o, (c + 0.5) * cell, (r + 0.5) * cell, cell * 0.32)

    for i, (r, c) in enumerate(state.agent_rc[0].tolist()):
        cx, cy, q = (c + 0.5) * cell, (r + 0.5) * cell, cell * 0.36
        draw.ellipse((cx - q, cy - q, cx + q, cy + q), fill=AGENT_COLOURS[i], outline=DARK, width=2)
        draw.text((cx - 3, cy - 6), str(i), fill="white")
        held = np.flatnonzero(state.obj_holder[0] == i)
        if held.size:
            _object(
                draw,
                layout,
                state,
                int(held[0]),
                cx + 0.45 * cell * 0.5,
                cy + 0.45 * cell * 0.5,
                cell * 0.2,
            )

    for i, name in enumerate(recipes):
        y = height * cell + LEGEND_LINE * i + 2
        draw.rectangle((4, y + 1, 14, y + 11), fill=AGENT_COLOURS[i])
        served = "  (served)" if bool(state.delivered[0, i]) else ""
        draw.text((20, y), f"agent {i}: {name}{served}", fill=DARK)
    return np.asarray(image, dtype=np.uint8)
