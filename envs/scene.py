"""Scenes: an environment drawn as shapes in its own units, for the web console to paint.

A PettingZoo `render()` gives pixels; the console wants to draw the world itself (SVG), label
every element for screen readers and let a test read where each agent is. A domain therefore
describes its env as a `Scene` (what does not move: areas, walls, stations; once per episode)
and a `SceneFrame` per step (the agents and the objects that move), both from
`Drawing.scene(env)` / `Drawing.scene_frame(env)` (`envs.registry`: an environment's
registration; `PlainDrawing` where it gives none). The console's painter knows only these
shapes, never an environment. `to_json` writes plain Python numbers and strings whatever the
env handed in (numpy scalars included), so any env's scene can be streamed as JSON.

| shape    | fields used                       | drawn as                                   |
|----------|-----------------------------------|--------------------------------------------|
| `rect`   | x, y (lower-left or top-left), w, h | rectangle; `dash` for an outline only     |
| `circle` | x, y (centre), r                  | disc                                       |
| `line`   | x, y to x2, y2                    | line                                       |
| `text`   | x, y (centre), text, h (size)     | a short word, `h` world units tall         |

Every shape has a `label` (what a screen reader says, and the tooltip), `fill` / `stroke` as
`#rrggbb` or None, and an `opacity`. Coordinates are world units: x to the right; y up when the
scene's `y_up` (the particle world's unit square) and down otherwise (the kitchen's rows).
An `AgentMark` is one agent's position and state: its own class, so the painter can draw agents
above everything else and a test can read their positions.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal, TypeAlias

import numpy as np

ShapeKind = Literal["rect", "circle", "line", "text"]
Number: TypeAlias = float | np.floating[Any] | np.integer[Any]
"""A coordinate or size: a Python number or a numpy scalar (`to_json` makes it a float)."""
DIGITS = 4  # coordinates are rounded in JSON: far below a pixel at any sensible zoom


def _number(value: Any, field: str) -> float:
    """`value` as a plain, finite float rounded to `DIGITS` (a numpy scalar is not JSON to
    every encoder); ValueError naming the field otherwise."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{field}: expected a number, got {value!r}") from None
    if number != number or number in (float("inf"), float("-inf")):
        raise ValueError(f"{field}: expected a finite number, got {number}")
    return round(number, DIGITS)


def hex_colour(rgb: Sequence[int]) -> str:
    """(r, g, b) in 0..255 -> "#rrggbb"."""
    r, g, b = (int(v) for v in rgb[:3])
    if not all(0 <= v <= 255 for v in (r, g, b)):
        raise ValueError(f"rgb: expected three values in 0..255, got {tuple(rgb)}")
    return f"#{r:02x}{g:02x}{b:02x}"


@dataclass(frozen=True)
class Shape:
    kind: ShapeKind
    x: Number
    y: Number
    w: Number = 0.0  # rect: width; line: x2
    h: Number = 0.0  # rect: height; line: y2; text: font size
    r: Number = 0.0  # circle: radius
    fill: str | None = None
    stroke: str | None = None
    opacity: Number = 1.0
    dash: bool = False  # a dashed outline
    text: str = ""
    label: str = ""

    def to_json(self) -> dict[str, Any]:
        where = f"shape {self.label or self.kind!r}"
        out: dict[str, Any] = {"kind": str(self.kind), "x": _number(self.x, f"{where}: x")}
        out["y"] = _number(self.y, f"{where}: y")
        if self.kind == "rect":
            out["w"], out["h"] = _number(self.w, f"{where}: w"), _number(self.h, f"{where}: h")
        elif self.kind == "line":
            out["x2"], out["y2"] = _number(self.w, f"{where}: x2"), _number(self.h, f"{where}: y2")
        elif self.kind == "circle":
            out["r"] = _number(self.r, f"{where}: r")
        elif self.kind == "text":
            out["size"] = _number(self.h, f"{where}: size")
        for key in ("fill", "stroke", "text", "label"):
            value = getattr(self, key)
            if value:
                out[key] = str(value)
        if self.opacity != 1.0:
            out["opacity"] = _number(self.opacity, f"{where}: opacity")
        if self.dash:
            out["dash"] = True
        return out


def rect(x: Number, y: Number, w: Number, h: Number, **style: Any) -> Shape:
    return Shape("rect", x, y, w=w, h=h, **style)


def circle(x: Number, y: Number, r: Number, **style: Any) -> Shape:
    return Shape("circle", x, y, r=r, **style)


def line(x: Number, y: Number, x2: Number, y2: Number, **style: Any) -> Shape:
    return Shape("line", x, y, w=x2, h=y2, **style)


def text(x: Number, y: Number, content: str, size: Number, **style: Any) -> Shape:
    return Shape("text", x, y, h=size, text=content, **style)


@dataclass(frozen=True)
class Scene:
    """What does not move, and how to read the units."""

    width: Number
    height: Number
    y_up: bool
    agent_radius: Number  # in world units
    agent_colours: tuple[str, ...]  # one per agent, "#rrggbb"
    shapes: tuple[Shape, ...]

    def to_json(self) -> dict[str, Any]:
        return {
            "width": _number(self.width, "scene: width"),
            "height": _number(self.height, "scene: height"),
            "y_up": bool(self.y_up),
            "agent_radius": _number(self.agent_radius, "scene: agent_radius"),
            "agent_colours": [str(c) for c in self.agent_colours],
            "shapes": [s.to_json() for s in self.shapes],
        }


@dataclass(frozen=True)
class AgentMark:
    index: int | np.integer[Any]
    x: Number
    y: Number
    label: str  # e.g. "agent 0 (a2) at 0.31, 0.52, in its target area"
    status: str = ""  # a short state word: "in target", "served", "holds tomato"

    def to_json(self) -> dict[str, Any]:
        where = f"agent {self.index}"
        out: dict[str, Any] = {"index": int(self.index), "x": _number(self.x, f"{where}: x")}
        out["y"] = _number(self.y, f"{where}: y")
        out["label"] = str(self.label)
        if self.status:
            out["status"] = str(self.status)
        return out


@dataclass(frozen=True)
class SceneFrame:
    """What moves: the agents, and shapes for the objects (drawn above the agents, so what an
    agent holds shows on its disc)."""

    agents: tuple[AgentMark, ...]
    shapes: tuple[Shape, ...] = ()

    def to_json(self) -> dict[str, Any]:
        return {
            "agents": [a.to_json() for a in self.agents],
            "shapes": [s.to_json() for s in self.shapes],
        }
