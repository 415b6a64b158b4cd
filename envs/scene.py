"""Scenes: an environment drawn as shapes in its own units, for the web console to paint.

A PettingZoo `render()` gives pixels; the console wants to draw the world itself (SVG), label
every element for screen readers and let a test read where each agent is. A domain therefore
describes its env as a `Scene` (what does not move: areas, walls, stations; once per episode)
and a `SceneFrame` per step (the agents and the objects that move), both from
`Domain.scene(env)` / `Domain.scene_frame(env)` (`envs.base`). The console's painter knows
only these shapes, never an environment.

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
from typing import Any, Literal

ShapeKind = Literal["rect", "circle", "line", "text"]
DIGITS = 4  # coordinates are rounded in JSON: far below a pixel at any sensible zoom


def hex_colour(rgb: Sequence[int]) -> str:
    """(r, g, b) in 0..255 -> "#rrggbb"."""
    r, g, b = (int(v) for v in rgb[:3])
    if not all(0 <= v <= 255 for v in (r, g, b)):
        raise ValueError(f"rgb: expected three values in 0..255, got {tuple(rgb)}")
    return f"#{r:02x}{g:02x}{b:02x}"


@dataclass(frozen=True)
class Shape:
    kind: ShapeKind
    x: float
    y: float
    w: float = 0.0  # rect: width; line: x2
    h: float = 0.0  # rect: height; line: y2; text: font size
    r: float = 0.0  # circle: radius
    fill: str | None = None
    stroke: str | None = None
    opacity: float = 1.0
    dash: bool = False  # a dashed outline
    text: str = ""
    label: str = ""

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"kind": self.kind, "x": round(self.x, DIGITS)}
        out["y"] = round(self.y, DIGITS)
        if self.kind == "rect":
            out["w"], out["h"] = round(self.w, DIGITS), round(self.h, DIGITS)
        elif self.kind == "line":
            out["x2"], out["y2"] = round(self.w, DIGITS), round(self.h, DIGITS)
        elif self.kind == "circle":
            out["r"] = round(self.r, DIGITS)
        elif self.kind == "text":
            out["size"] = round(self.h, DIGITS)
        for key in ("fill", "stroke", "text", "label"):
            value = getattr(self, key)
            if value:
                out[key] = value
        if self.opacity != 1.0:
            out["opacity"] = self.opacity
        if self.dash:
            out["dash"] = True
        return out


def rect(x: float, y: float, w: float, h: float, **style: Any) -> Shape:
    return Shape("rect", x, y, w=w, h=h, **style)


def circle(x: float, y: float, r: float, **style: Any) -> Shape:
    return Shape("circle", x, y, r=r, **style)


def line(x: float, y: float, x2: float, y2: float, **style: Any) -> Shape:
    return Shape("line", x, y, w=x2, h=y2, **style)


def text(x: float, y: float, content: str, size: float, **style: Any) -> Shape:
    return Shape("text", x, y, h=size, text=content, **style)


@dataclass(frozen=True)
class Scene:
    """What does not move, and how to read the units."""

    width: float
    height: float
    y_up: bool
    agent_radius: float  # in world units
    agent_colours: tuple[str, ...]  # one per agent, "#rrggbb"
    shapes: tuple[Shape, ...]

    def to_json(self) -> dict[str, Any]:
        return {
            "width": self.width,
            "height": self.height,
            "y_up": self.y_up,
            "agent_radius": self.agent_radius,
            "agent_colours": list(self.agent_colours),
            "shapes": [s.to_json() for s in self.shapes],
        }


@dataclass(frozen=True)
class AgentMark:
    index: int
    x: float
    y: float
    label: str  # e.g. "agent 0 (a2) at 0.31, 0.52, in its target area"
    status: str = ""  # a short state word: "in target", "served", "holds tomato"

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"index": self.index, "x": round(self.x, DIGITS)}
        out["y"] = round(self.y, DIGITS)
        out["label"] = self.label
        if self.status:
            out["status"] = self.status
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
