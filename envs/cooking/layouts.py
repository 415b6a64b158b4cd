"""Kitchens as text: a one-character-per-cell grid language, its parser and the built-in layouts.

| char          | cell                                                   | holds an item         |
|---------------|--------------------------------------------------------|-----------------------|
| `.`           | floor (agents walk here)                               | no                    |
| `0`..`3`      | floor where agent 0..3 starts                          | no                    |
| `#`           | wall: blocks, nothing happens when walked into         | no                    |
| `=`           | empty counter                                          | one item              |
| `/`           | cutting board (chops a raw ingredient)                 | one lone ingredient   |
| `B`           | blender (blends a raw ingredient)                      | one lone ingredient   |
| `*`           | delivery square (a plate walked onto it is delivered)  | never                 |
| `p`           | counter with a plate on it                             | one item              |
| `t l o c b`   | counter with a tomato, lettuce, onion, carrot, banana  | one item              |

Rules of the language: at most 16 × 16 cells; every line as long as the first; the agents are the
digits 0..N-1, each exactly once (N <= 4); at most 2 of each ingredient, 4 plates and 2 of each
station (cutting board, blender, delivery square), because the observation has that many slots.
Blank lines before and after the grid and a common indentation are ignored; cells outside the grid
count as walls. Errors are `LayoutError`s naming the line and column (1-based, in the text given).

| built-in      | size  | what                                                              |
|---------------|-------|-------------------------------------------------------------------|
| `coexistence` | 11×5  | paper Fig. 8: two rooms joined only by one pass-through counter   |
|               |       | (line 2, column 6). Left (agent 0): tomato, lettuce, carrot, board,|
|               |       | plate, delivery. Right (agent 1): banana, board, plate, delivery. |
|               |       | CarrotBanana on the right needs the left room's carrot.           |
| `open`        | 11×7  | one room: every ingredient (two tomatoes), two plates, two boards,|
|               |       | two blenders, two delivery squares; both agents reach everything  |
| `split`       | 11×5  | forced coordination: ingredients and plates in the left room,     |
|               |       | boards, blender and delivery in the right room, three shared      |
|               |       | pass-through counters between them; nobody can cook alone         |
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from envs.cooking.recipes import INGREDIENTS, PLATE

MAX_AGENTS = 4
MAX_LAYOUT_SIZE = 16
MAX_PER_INGREDIENT = 2
MAX_PLATES = 4
MAX_PER_STATION = 2

FLOOR, WALL, COUNTER, BOARD, BLENDER, DELIVERY = range(6)
CELL_NAMES = ("floor", "wall", "counter", "cutting_board", "blender", "delivery")
STATION_KINDS = (BOARD, BLENDER, DELIVERY)

_CELL_OF_CHAR = {".": FLOOR, "#": WALL, "=": COUNTER, "/": BOARD, "B": BLENDER, "*": DELIVERY}
_OBJECT_OF_CHAR = {"t": 0, "l": 1, "o": 2, "c": 3, "b": 4, "p": PLATE}
_AGENT_CHARS = "0123"
VALID_CHARS = "".join(_CELL_OF_CHAR) + "".join(_OBJECT_OF_CHAR) + _AGENT_CHARS


class LayoutError(ValueError):
    """A layout text that breaks the grid language; `line` and `column` are 1-based."""

    def __init__(self, message: str, line: int | None = None, column: int | None = None) -> None:
        where = (
            ""
            if line is None
            else f"line {line}" + ("" if column is None else f", column {column}")
        )
        super().__init__(f"layout: {where + ': ' if where else ''}{message}")
        self.line, self.column = line, column


@dataclass(frozen=True, eq=False)
class Layout:
    """A parsed kitchen. Arrays are read-only; positions are (row, column), row 0 at the top."""

    name: str
    rows: tuple[str, ...]
    cells_HW: np.ndarray  # cell kind (FLOOR .. DELIVERY)
    object_kinds_O: np.ndarray  # ingredient kind 0..4 or PLATE, in reading order
    object_starts_O2: np.ndarray
    agent_starts_N2: np.ndarray
    stations: dict[int, np.ndarray] = field(repr=False)  # station kind -> (k, 2) positions
    floor_region_HW: np.ndarray = field(repr=False)  # connected floor area id, -1 off the floor
    _hash: int = field(init=False, repr=False, default=0)

    @property
    def shape(self) -> tuple[int, int]:
        return (len(self.rows), len(self.rows[0]))

    @property
    def n_agents(self) -> int:
        return int(self.agent_starts_N2.shape[0])

    @property
    def n_objects(self) -> int:
        return int(self.object_kinds_O.shape[0])

    def text(self) -> str:
        return "\n".join(self.rows)

    # Equal grids are equal layouts (whatever the name): per-layout caches key on the grid.
    def __eq__(self, other: object) -> bool:
        return isinstance(other, Layout) and self.rows == other.rows

    def __hash__(self) -> int:
        return self._hash

    def __post_init__(self) -> None:
        object.__setattr__(self, "_hash", hash(self.rows))  # hashed on every cache look-up


def _grid_lines(text: str) -> tuple[list[tuple[int, str]], int]:
    """(1-based line number, row) pairs without surrounding blank lines, and the common indent."""
    numbered = [(i + 1, line.rstrip()) for i, line in enumerate(text.splitlines())]
    while numbered and not numbered[0][1]:
        numbered.pop(0)
    while numbered and not numbered[-1][1]:
        numbered.pop()
    if not numbered:
        raise LayoutError("the text holds no grid")
    indent = min(len(row) - len(row.lstrip(" ")) for _, row in numbered if row)
    return [(n, row[indent:]) for n, row in numbered], indent


def _floor_regions(cells_HW: np.ndarray) -> np.ndarray:
    """Label the 4-connected floor areas 0, 1, ...; -1 elsewhere."""
    height, width = cells_HW.shape
    region = np.full(cells_HW.shape, -1, dtype=np.int64)
    label = 0
    for start in zip(*np.nonzero(cells_HW == FLOOR), strict=True):
        if region[start] >= 0:
            continue
        region[start] = label
        queue = deque([start])
        while queue:
            r, c = queue.popleft()
            for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
                inside = 0 <= nr < height and 0 <= nc < width
                if inside and cells_HW[nr, nc] == FLOOR and region[nr, nc] < 0:
                    region[nr, nc] = label
                    queue.append((nr, nc))
        label += 1
    return region


def _read_only(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


def parse_layout(text: str, name: str = "custom") -> Layout:
    """Parse a kitchen written in the grid language (see the module docstring)."""
    lines, indent = _grid_lines(text)
    width = len(lines[0][1])
    if len(lines) > MAX_LAYOUT_SIZE or width > MAX_LAYOUT_SIZE:
        raise LayoutError(
            f"the grid is {len(lines)} × {width} cells, at most "
            f"{MAX_LAYOUT_SIZE} × {MAX_LAYOUT_SIZE} are allowed"
        )
    cells = np.full((len(lines), width), WALL, dtype=np.int64)
    objects: list[tuple[int, int, int]] = []
    agents: dict[int, tuple[int, int]] = {}
    counts: dict[str, int] = {}
    for r, (line_no, row) in enumerate(lines):
        if len(row) != width:
            raise LayoutError(
                f"expected {width} cells like the first line, got {len(row)}", line_no
            )
        for c, char in enumerate(row):
            column = indent + c + 1
            if char not in VALID_CHARS:
                raise LayoutError(
                    f"unknown cell {char!r} (expected one of {' '.join(VALID_CHARS)})",
                    line_no,
                    column,
                )
            if char in _AGENT_CHARS:
                if int(char) in agents:
                    raise LayoutError(f"agent {char} starts twice", line_no, column)
                agents[int(char)] = (r, c)
                cells[r, c] = FLOOR
                continue
            if char in _OBJECT_OF_CHAR:
                kind = _OBJECT_OF_CHAR[char]
                cells[r, c] = COUNTER
                objects.append((kind, r, c))
                label = "plate" if kind == PLATE else INGREDIENTS[kind]
                limit = MAX_PLATES if kind == PLATE else MAX_PER_INGREDIENT
            else:
                cells[r, c] = _CELL_OF_CHAR[char]
                label, limit = CELL_NAMES[cells[r, c]], MAX_PER_STATION
                if cells[r, c] not in STATION_KINDS:
                    continue
            counts[label] = counts.get(label, 0) + 1
            if counts[label] > limit:
                raise LayoutError(f"more than {limit} {label} cells", line_no, column)
    if not agents:
        raise LayoutError("no agent start (digits 0..3)")
    missing = [str(i) for i in range(len(agents)) if i not in agents]
    if missing:
        raise LayoutError(
            f"agents must be numbered 0..{len(agents) - 1}; missing {', '.join(missing)}"
        )
    stations = {
        k: _read_only(np.argwhere(cells == k).astype(np.int64).reshape(-1, 2))
        for k in STATION_KINDS
    }
    return Layout(
        name=name,
        rows=tuple(row for _, row in lines),
        cells_HW=_read_only(cells),
        object_kinds_O=_read_only(np.array([o[0] for o in objects], dtype=np.int64)),
        object_starts_O2=_read_only(
            np.array([o[1:] for o in objects], dtype=np.int64).reshape(-1, 2)
        ),
        agent_starts_N2=_read_only(
            np.array([agents[i] for i in range(len(agents))], dtype=np.int64)
        ),
        stations=stations,
        floor_region_HW=_read_only(_floor_regions(cells)),
    )


BUILTIN_LAYOUTS: dict[str, str] = {
    "coexistence": """
        #t=l=#==b=#
        c....=....p
        /.0..#..1./
        =....#....=
        #p*==#=*==#
    """,
    "open": """
        #=t=l=o=c=#
        p.........b
        /....0....=
        =.........t
        B....1....=
        p.........=
        #=*=/=B=*=#
    """,
    "split": """
        #t=l=#=/==#
        o....=....*
        p.0..=..1.B
        c....=....*
        #b=p=#=/==#
    """,
}

_PARSED: dict[str, Layout] = {}


def load_layout(path: str | Path) -> Layout:
    """Parse a layout file (its stem becomes the layout's name)."""
    path = Path(path)
    return parse_layout(path.read_text(encoding="utf-8"), name=path.stem)


def get_layout(layout: str | Layout) -> Layout:
    """A `Layout` from a built-in name, a layout text (several lines) or a `Layout` itself."""
    if isinstance(layout, Layout):
        return layout
    if not isinstance(layout, str):
        raise ValueError(f"layout: expected a name, a layout text or a Layout, got {layout!r}")
    if layout in BUILTIN_LAYOUTS:
        if layout not in _PARSED:
            _PARSED[layout] = parse_layout(BUILTIN_LAYOUTS[layout], name=layout)
        return _PARSED[layout]
    if "\n" in layout:
        return parse_layout(layout)
    raise ValueError(
        f"layout: unknown layout {layout!r} (built-ins: {', '.join(BUILTIN_LAYOUTS)}; "
        "or pass a layout text of several lines)"
    )
