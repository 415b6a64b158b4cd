"""The particle world as a `envs.scene.Scene` (the web console draws it; `render.py` draws pixels).

| element        | shape                                                         |
|----------------|---------------------------------------------------------------|
| grid           | thin lines of the 5×5 goal grid                               |
| target area    | rectangle filled in the agent's colour, translucent           |
| influence area | rectangle outlined (dashed) in the agent's colour             |
| agent          | `AgentMark` at (x, y); the painter draws it in its colour     |

Units are the world's: the unit square, y up. Colours are `render.AGENT_COLOURS`, so the
console, the GIFs and the plots show an agent in one colour.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from envs.particle.goals import GRID_SIZE, INFLUENCE_BOXES_G4, TARGET_BOXES_G4, goal_index
from envs.particle.render import AGENT_COLOURS, TARGET_ALPHA
from envs.particle.world import in_target
from envs.scene import AgentMark, Scene, SceneFrame, Shape, hex_colour, line, rect

AGENT_RADIUS = 0.025  # the GIF's disc: size / 40 of the side
GRID_STROKE = "#c8c8c8"


def _check_goals(goals: Sequence[str]) -> list[int]:
    if not 1 <= len(goals) <= len(AGENT_COLOURS):
        raise ValueError(f"goals: expected 1..{len(AGENT_COLOURS)} goals, got {len(goals)}")
    return [goal_index(g) for g in goals]


def _box(box: np.ndarray, **style: object) -> Shape:
    x_lo, x_hi, y_lo, y_hi = (float(v) for v in box)
    return rect(x_lo, y_lo, x_hi - x_lo, y_hi - y_lo, **style)


def particle_scene(goals: Sequence[str]) -> Scene:
    """The grid and every agent's target and influence areas (agent i has goal `goals[i]`)."""
    indices = _check_goals(goals)
    shapes: list[Shape] = []
    for k in range(GRID_SIZE + 1):
        p = k / GRID_SIZE
        shapes.append(line(p, 0.0, p, 1.0, stroke=GRID_STROKE))
        shapes.append(line(0.0, p, 1.0, p, stroke=GRID_STROKE))
    colours = [hex_colour(c) for c in AGENT_COLOURS[: len(goals)]]
    for i, (goal, g) in enumerate(zip(goals, indices, strict=True)):
        shapes.append(
            _box(
                TARGET_BOXES_G4[g],
                fill=colours[i],
                opacity=round(TARGET_ALPHA / 255, 3),
                label=f"target area of agent {i} (goal {goal})",
            )
        )
    for i, (goal, g) in enumerate(zip(goals, indices, strict=True)):
        shapes.append(
            _box(
                INFLUENCE_BOXES_G4[g],
                stroke=colours[i],
                dash=True,
                label=f"influence area of agent {i} (goal {goal})",
            )
        )
    return Scene(1.0, 1.0, True, AGENT_RADIUS, tuple(colours), tuple(shapes))


def particle_frame(goals: Sequence[str], state_N4: np.ndarray) -> SceneFrame:
    """The agents at `state_N4` (one `[x, y, vx, vy]` row per agent, in agent order)."""
    indices = _check_goals(goals)
    state_N4 = np.asarray(state_N4, dtype=np.float64)
    if state_N4.shape != (len(goals), 4):
        raise ValueError(f"state_N4: expected shape ({len(goals)}, 4), got {state_N4.shape}")
    inside_N = in_target(state_N4, np.asarray(indices, dtype=np.int64))
    marks = []
    for i, (goal, (x, y, _, _)) in enumerate(zip(goals, state_N4.tolist(), strict=True)):
        status = "in target" if inside_N[i] else ""
        where = f"at {x:.2f}, {y:.2f}" + (", in its target area" if status else "")
        marks.append(AgentMark(i, x, y, f"agent {i} (goal {goal}) {where}", status))
    return SceneFrame(tuple(marks))
