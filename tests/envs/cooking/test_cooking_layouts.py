"""The grid language: parsing, errors with line and column, the built-in kitchens' geometry."""

from pathlib import Path

import numpy as np
import pytest

from envs.cooking.layouts import (
    BLENDER,
    BOARD,
    BUILTIN_LAYOUTS,
    COUNTER,
    DELIVERY,
    FLOOR,
    WALL,
    LayoutError,
    get_layout,
    load_layout,
    parse_layout,
)
from envs.cooking.navigation import can_reach
from envs.cooking.recipes import PLATE


def test_parse_cells_objects_agents_and_indentation() -> None:
    layout = parse_layout(
        """

        #t/B
        10.*
        p==#
        """,
        name="tiny",
    )
    assert layout.name == "tiny" and layout.shape == (3, 4) and layout.n_agents == 2
    assert layout.cells_HW.tolist() == [
        [WALL, COUNTER, BOARD, BLENDER],
        [FLOOR, FLOOR, FLOOR, DELIVERY],
        [COUNTER, COUNTER, COUNTER, WALL],
    ]
    assert layout.object_kinds_O.tolist() == [0, PLATE]  # reading order: tomato, plate
    assert layout.object_starts_O2.tolist() == [[0, 1], [2, 0]]
    assert layout.agent_starts_N2.tolist() == [[1, 1], [1, 0]]  # by digit, not reading order
    assert layout.stations[DELIVERY].tolist() == [[1, 3]]
    assert layout.floor_region_HW[1].tolist() == [0, 0, 0, -1]
    assert layout.text() == "#t/B\n10.*\np==#"


@pytest.mark.parametrize(
    ("text", "line", "column", "match"),
    [
        ("#0#\n#x#", 2, 2, "unknown cell 'x'"),
        ("  #0#\n  #x#", 2, 4, "unknown cell 'x'"),  # column counts the indentation
        ("#0#\n#..#", 2, None, "expected 3 cells"),
        ("#00#", 1, 3, "agent 0 starts twice"),
        ("#0ttt#", 1, 5, "more than 2 tomato"),
        ("#0ppppp#", 1, 7, "more than 4 plate"),
        ("#0///#", 1, 5, "more than 2 cutting_board"),
    ],
)
def test_errors_name_line_and_column(text: str, line: int, column: int | None, match: str) -> None:
    with pytest.raises(LayoutError, match=match) as info:
        parse_layout(text)
    assert (info.value.line, info.value.column) == (line, column)
    assert isinstance(info.value, ValueError)


def test_errors_without_a_position() -> None:
    with pytest.raises(LayoutError, match="no grid"):
        parse_layout("\n   \n")
    with pytest.raises(LayoutError, match="no agent"):
        parse_layout("#..#")
    with pytest.raises(LayoutError, match="missing 1"):
        parse_layout("#0.2#")
    with pytest.raises(LayoutError, match="at most 16"):
        parse_layout("0" + "." * 16)


def test_get_layout_and_files(tmp_path: Path) -> None:
    assert get_layout("open") is get_layout("open")  # parsed once
    custom = get_layout("#0t\n#*p")
    assert custom.n_objects == 2
    path = tmp_path / "galley.txt"
    path.write_text("#0t/*p#\n", encoding="utf-8")
    assert load_layout(path).name == "galley"
    with pytest.raises(ValueError, match="unknown layout 'kitchen'"):
        get_layout("kitchen")


def _cells(rows: list[list[int]]) -> list[tuple[int, int]]:
    return [(r, c) for r, c in rows]


def _reachable_kinds(name: str, agent: int) -> set[int]:
    layout = get_layout(name)
    me = tuple(layout.agent_starts_N2[agent].tolist())
    return {
        int(kind)
        for kind, rc in zip(layout.object_kinds_O, layout.object_starts_O2.tolist(), strict=True)
        if can_reach(layout, me, tuple(rc))
    }


def test_coexistence_geometry() -> None:
    """Fig. 8: the carrot only the left cook reaches; one counter both reach."""
    layout = get_layout("coexistence")
    left, right = _cells(layout.agent_starts_N2.tolist())
    assert _reachable_kinds("coexistence", 0) == {0, 1, 3, PLATE}  # tomato, lettuce, carrot
    assert _reachable_kinds("coexistence", 1) == {4, PLATE}  # banana
    counters = _cells(np.argwhere(layout.cells_HW == COUNTER).tolist())
    shared = [c for c in counters if can_reach(layout, left, c) and can_reach(layout, right, c)]
    assert shared == [(1, 5)]
    for station in (BOARD, DELIVERY):
        cells = _cells(layout.stations[station].tolist())
        assert any(can_reach(layout, left, c) for c in cells)
        assert any(can_reach(layout, right, c) for c in cells)


def test_open_and_split_geometry() -> None:
    assert _reachable_kinds("open", 0) == _reachable_kinds("open", 1) == {0, 1, 2, 3, 4, PLATE}
    assert _reachable_kinds("split", 1) == set()  # the right cook reaches no ingredient ...
    split = get_layout("split")
    right = tuple(split.agent_starts_N2[1].tolist())
    left = tuple(split.agent_starts_N2[0].tolist())
    for station in (BOARD, BLENDER, DELIVERY):  # ... and the left cook no station
        for cell in split.stations[station].tolist():
            assert can_reach(split, right, tuple(cell)) and not can_reach(split, left, tuple(cell))
    assert set(BUILTIN_LAYOUTS) == {"coexistence", "open", "split"}
