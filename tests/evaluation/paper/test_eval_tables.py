"""The report's tables built from known cells: every row shows its own comparison's numbers."""

from __future__ import annotations

import pytest

from evaluation.paper import tables
from evaluation.stats import Interval, MeanSE, PairedTest

MEASURES = ("ego return", "team return")


def known_tests() -> list[PairedTest]:
    """Three comparisons, two of them against SL, each with numbers no other row has: the
    difference is 10 × pair number + measure number, the p 10^-(pair number)."""
    pairs = [("aail", "sl"), ("aail", "nail"), ("aail_bounded", "sl")]
    return [
        PairedTest(
            measure,
            method,
            other,
            30,
            MeanSE(10.0 * i + j, 0.5),
            10.0**-i,
            "wilcoxon",
            Interval(10.0 * i + j - 1, 10.0 * i + j + 1, 0.95),
            i / 10,
        )
        for i, (method, other) in enumerate(pairs, 1)
        for j, measure in enumerate(MEASURES, 1)
    ]


def rows_of(markdown: str) -> dict[str, list[str]]:
    """Body rows keyed by their first cell."""
    lines = markdown.splitlines()[2:]
    cells = [[c.strip() for c in line.strip("|").split("|")] for line in lines]
    return {row[0]: row[1:] for row in cells}


def test_each_row_shows_its_own_pair() -> None:
    rows = rows_of(tables.tests_table(known_tests()))
    # AAIL − SL and AAIL-B − SL share `other`: each keeps its own numbers and its own label
    assert list(rows) == ["AAIL − SL", "AAIL − NAIL", "AAIL-B − SL"]
    assert rows["AAIL − SL"] == ["11.00 ± 0.50 (p = 0.1)", "12.00 ± 0.50 (p = 0.1)"]
    assert rows["AAIL − NAIL"] == ["21.00 ± 0.50 (p = 0.01)", "22.00 ± 0.50 (p = 0.01)"]
    assert rows["AAIL-B − SL"] == ["31.00 ± 0.50 (p = 0.001)", "32.00 ± 0.50 (p = 0.001)"]


def test_a_comparison_given_twice_is_refused() -> None:
    tests = known_tests()
    with pytest.raises(ValueError, match="AAIL − SL on ego return twice"):
        tables.tests_table([*tests, tests[0]])
