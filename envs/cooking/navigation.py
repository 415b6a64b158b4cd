"""Walking on a kitchen's floor: shortest paths, reachability, and the action that walks towards
(or into) a counter or station. Used by the scripted cooks; pure functions of a `Layout`.

Cells are (row, column) tuples. An agent *uses* a counter cell by standing on one of its floor
neighbours (an *approach*) and walking into it. Distances ignore the agents (a table computed once
per layout by breadth-first search) and choose targets; the path itself is a breadth-first search
that treats the other agents' cells as walls, so a cook walks round them, or waits when shut in.
"""

from __future__ import annotations

import functools
from collections import deque
from collections.abc import Iterable

import numpy as np

from envs.cooking.layouts import FLOOR, Layout
from envs.cooking.world import ACTION_DELTAS_A2

Cell = tuple[int, int]
UNREACHABLE = 1 << 20
STAY = 0
_MOVES = [(a, (int(d[0]), int(d[1]))) for a, d in enumerate(ACTION_DELTAS_A2.tolist()) if a != STAY]
_OPPOSITE = {1: 2, 2: 1, 3: 4, 4: 3}


class _Geometry:
    """A layout's floor graph, computed once: neighbours, approaches and all floor distances."""

    def __init__(self, layout: Layout) -> None:
        height, width = layout.shape
        floor = layout.cells_HW == FLOOR
        self.width = width
        self.neighbours: dict[Cell, list[tuple[int, Cell]]] = {}
        for r in range(height):
            for c in range(width):
                self.neighbours[(r, c)] = [
                    (a, (r + dr, c + dc))
                    for a, (dr, dc) in _MOVES
                    if 0 <= r + dr < height and 0 <= c + dc < width and floor[r + dr, c + dc]
                ]
        self.approaches = {
            cell: [(nxt, _OPPOSITE[a]) for a, nxt in moves]
            for cell, moves in self.neighbours.items()
        }
        self.distances = [[UNREACHABLE] * (height * width) for _ in range(height * width)]
        for cell in zip(*np.nonzero(floor), strict=True):
            src = (int(cell[0]), int(cell[1]))
            row = self.distances[src[0] * width + src[1]]
            row[src[0] * width + src[1]] = 0
            queue = deque([src])
            while queue:
                here = queue.popleft()
                for _, nxt in self.neighbours[here]:
                    if row[nxt[0] * width + nxt[1]] == UNREACHABLE:
                        row[nxt[0] * width + nxt[1]] = row[here[0] * width + here[1]] + 1
                        queue.append(nxt)

    def distance(self, a: Cell, b: Cell) -> int:
        return self.distances[a[0] * self.width + a[1]][b[0] * self.width + b[1]]


@functools.lru_cache(maxsize=64)
def _geometry(layout: Layout) -> _Geometry:
    return _Geometry(layout)


def distance(layout: Layout, a: Cell, b: Cell) -> int:
    """Floor steps from a to b, ignoring agents (UNREACHABLE across walls or off the floor)."""
    return _geometry(layout).distance(a, b)


def approaches(layout: Layout, cell: Cell) -> list[tuple[Cell, int]]:
    """(floor cell, action) pairs: standing on the floor cell, the action walks into `cell`."""
    return _geometry(layout).approaches[cell]


def cost(layout: Layout, agent: Cell, cell: Cell, blocked: frozenset[Cell] = frozenset()) -> int:
    """Steps to reach a free floor cell next to `cell` (UNREACHABLE if there is none)."""
    geometry = _geometry(layout)
    return min(
        (geometry.distance(agent, a) for a, _ in geometry.approaches[cell] if a not in blocked),
        default=UNREACHABLE,
    )


def can_reach(layout: Layout, agent: Cell, cell: Cell) -> bool:
    return cost(layout, agent, cell) < UNREACHABLE


def nearest(
    layout: Layout, agent: Cell, blocked: frozenset[Cell], cells: Iterable[Cell]
) -> Cell | None:
    """The reachable cell of `cells` the agent can use soonest (ties: the first given). Cells whose
    every approach is `blocked` (by other agents) come last, so a cook picks a free station."""
    best, best_cost = None, (UNREACHABLE, UNREACHABLE)
    for cell in cells:
        c = (cost(layout, agent, cell, blocked), cost(layout, agent, cell))
        if c[1] < UNREACHABLE and c < best_cost:
            best, best_cost = cell, c
    return best


def _detour(layout: Layout, agent: Cell, goals: set[Cell], blocked: set[Cell]) -> int:
    """First action of a shortest path to `goals` that avoids `blocked`; STAY if there is none."""
    neighbours = _geometry(layout).neighbours
    first: dict[Cell, int] = {agent: STAY}
    queue = deque([agent])
    while queue:
        cell = queue.popleft()
        if cell in goals:
            return first[cell]
        for action, nxt in neighbours[cell]:
            if nxt not in first and nxt not in blocked:
                first[nxt] = action if cell == agent else first[cell]
                queue.append(nxt)
    return STAY


def action_towards(layout: Layout, agent: Cell, cell: Cell, blocked: set[Cell]) -> int:
    """The action that walks `agent` towards `cell` and, once next to it, into it.

    `blocked` holds the other agents' cells. STAY if `cell` is unreachable or the way is shut."""
    options = approaches(layout, cell)
    for floor, action in options:
        if floor == agent:
            return action
    goals = {f for f, _ in options if distance(layout, agent, f) < UNREACHABLE and f not in blocked}
    if not goals:
        return STAY
    return _detour(layout, agent, goals, blocked)
