"""The report's tables built from known cells: every row shows its own comparison's numbers."""

from __future__ import annotations

import pytest

from evaluation.paper import tables
from evaluation.stats import Interval, MeanSE, PairedTest, with_holm

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


def rows_of(markdown: str) -> dict[tuple[str, str], list[str]]:
    """Body rows keyed by their first two cells (comparison, measure)."""
    lines = markdown.splitlines()[2:]
    cells = [[c.strip() for c in line.strip("|").split("|")] for line in lines]
    return {(row[0], row[1]): row[2:] for row in cells}


def test_each_row_shows_its_own_pair() -> None:
    rows = rows_of(tables.tests_table(known_tests()))
    # AAIL − SL and AAIL-B − SL share `other`: each keeps its own numbers and its own label
    assert list(rows) == [
        (pair, measure)
        for pair in ("AAIL − SL", "AAIL − NAIL", "AAIL-B − SL")
        for measure in MEASURES
    ]
    # test, n, mean ± SE, 95 % CI, r, p, p (Holm): pair i, measure j -> 10 i + j, p = 10^-i
    assert rows[("AAIL − SL", "ego return")] == [
        "Wilcoxon",
        "30",
        "11.00 ± 0.50",
        "[10.00, 12.00]",
        "+0.10",
        "0.1",
        "-",
    ]
    assert rows[("AAIL − NAIL", "team return")] == [
        "Wilcoxon",
        "30",
        "22.00 ± 0.50",
        "[21.00, 23.00]",
        "+0.20",
        "0.01",
        "-",
    ]
    assert rows[("AAIL-B − SL", "ego return")] == [
        "Wilcoxon",
        "30",
        "31.00 ± 0.50",
        "[30.00, 32.00]",
        "+0.30",
        "0.001",
        "-",
    ]
    assert rows[("AAIL-B − SL", "team return")][2] == "32.00 ± 0.50"


def test_holm_adjusted_p_is_printed_beside_the_raw_one() -> None:
    family = with_holm(known_tests())
    rows = rows_of(tables.tests_table(family))
    # raw p's 0.1, 0.1, 0.01, 0.01, 0.001, 0.001: 0.001 × 6 = 0.006 for the smallest two
    assert rows[("AAIL-B − SL", "ego return")][-2:] == ["0.001", "0.006"]
    assert rows[("AAIL − NAIL", "ego return")][-2:] == ["0.01", "0.04"]  # 0.01 × 4
    assert rows[("AAIL − SL", "team return")][-2:] == ["0.1", "0.2"]  # max(0.1 × 2, 0.1 × 1)


def test_a_comparison_given_twice_is_refused() -> None:
    tests = known_tests()
    with pytest.raises(ValueError, match="AAIL − SL on ego return twice"):
        tables.tests_table([*tests, tests[0]])
