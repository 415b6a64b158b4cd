"""The 35 goals of the particle world (paper §4.1): 25 cells, 5 columns and 5 rows of a 5×5 grid.

A goal names a *target area* (where its agent wants to be) and an *influence area* (where it wants
the other agents to be). The paper fixes neither the grid naming nor where the influence area lies;
we take the influence area to be the point mirror of the target area through the world's centre
(x -> 1 - x, y -> 1 - y), so every goal has one and "aligned" pairs are easy to build by hand.

| id        | target area (x range × y range)                 | influence area (mirror)     |
|-----------|-------------------------------------------------|-----------------------------|
| `a0`..`e4`| letter = column (a: x∈[0, .2] .. e: x∈[.8, 1]), | `c4` -> `c0`, `b3` -> `d1`  |
|           | digit = row (0: y∈[0, .2] .. 4: y∈[.8, 1])      |                             |
| `a`..`e`  | the whole column, y∈[0, 1]                      | `a` -> `e`, `c` -> `c`      |
| `0`..`4`  | the whole row, x∈[0, 1]                         | `0` -> `4`, `2` -> `2`      |

Fixed order (the index used everywhere, e.g. in `goals_BN` arrays): the 25 cells column-major
(a0, a1, .., a4, b0, .., e4), then the columns a..e, then the rows 0..4.

| constant             | shape   | content                                    |
|----------------------|---------|--------------------------------------------|
| `GOAL_IDS`           | (35,)   | goal ids in the fixed order                |
| `TARGET_BOXES_G4`    | (35, 4) | target area (x_min, x_max, y_min, y_max)   |
| `INFLUENCE_BOXES_G4` | (35, 4) | influence area, same layout                |
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

GRID_SIZE = 5
CELL = 1.0 / GRID_SIZE
COLUMN_LETTERS = "abcde"

_CELLS = tuple(f"{col}{row}" for col in COLUMN_LETTERS for row in range(GRID_SIZE))
_COLUMNS = tuple(COLUMN_LETTERS)
_ROWS = tuple(str(row) for row in range(GRID_SIZE))

GOAL_IDS: tuple[str, ...] = _CELLS + _COLUMNS + _ROWS
N_GOALS = len(GOAL_IDS)
_INDEX = {goal: i for i, goal in enumerate(GOAL_IDS)}


def _target_box(goal: str) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max) of a goal's target area."""
    x_lo, x_hi, y_lo, y_hi = 0.0, 1.0, 0.0, 1.0
    for char in goal:
        if char in COLUMN_LETTERS:
            col = COLUMN_LETTERS.index(char)
            x_lo, x_hi = col * CELL, (col + 1) * CELL
        else:
            row = int(char)
            y_lo, y_hi = row * CELL, (row + 1) * CELL
    return x_lo, x_hi, y_lo, y_hi


def mirror_boxes(boxes_X4: np.ndarray) -> np.ndarray:
    """Point mirror of boxes through the world's centre: x -> 1 - x, y -> 1 - y."""
    x_lo, x_hi, y_lo, y_hi = np.moveaxis(boxes_X4, -1, 0)
    return np.stack([1.0 - x_hi, 1.0 - x_lo, 1.0 - y_hi, 1.0 - y_lo], axis=-1)


# Rounded so that edges shared by two areas are the same float (3 * 0.2 != 1 - 0.4 otherwise).
TARGET_BOXES_G4: np.ndarray = np.round([_target_box(g) for g in GOAL_IDS], 12)
INFLUENCE_BOXES_G4: np.ndarray = np.round(mirror_boxes(TARGET_BOXES_G4), 12)
TARGET_BOXES_G4.setflags(write=False)
INFLUENCE_BOXES_G4.setflags(write=False)


def goal_index(goal_id: str) -> int:
    """Index of `goal_id` in `GOAL_IDS`; ValueError naming the bad id otherwise."""
    try:
        return _INDEX[goal_id]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown goal {goal_id!r}: expected a cell a0..e4, a column a..e or a row 0..4"
        ) from None


def goal_indices(goal_ids: Iterable[str]) -> np.ndarray:
    """Indices of a sequence of goal ids, as an int array."""
    if isinstance(goal_ids, str):
        raise ValueError(f"goals: expected a sequence of goal ids, got the string {goal_ids!r}")
    return np.array([goal_index(g) for g in goal_ids], dtype=np.int64)
