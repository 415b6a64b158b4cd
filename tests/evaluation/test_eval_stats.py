"""Statistics helpers against hand-computed numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from evaluation.config import Scenario
from evaluation.rollout import CellResult
from evaluation.stats import (
    compare_cells,
    mcnemar_p,
    mean_se,
    paired_diff,
    summarise_cell,
    wilcoxon_p,
)

SCENARIO = Scenario("s", "a2", ("b3",), 4, 1)


def cell(method: str, returns: list[list[float]], success: list[bool]) -> CellResult:
    n = len(returns)
    return CellResult(
        scenario=SCENARIO,
        method=method,
        returns_EN=np.array(returns, dtype=float),
        success_EN=np.array([[s, True] for s in success]),
        reached_EN=np.array([[True, s] for s in success]),
        length_E=np.arange(1, n + 1) * 10,
        solved_E=np.array(success),
        trajectory_TN4=np.zeros((1, 2, 4)),
    )


def test_mean_se_by_hand() -> None:
    # mean 2.5; sample std sqrt(5/3) = 1.29099; se = 1.29099 / 2 = 0.645497
    m = mean_se([1.0, 2.0, 3.0, 4.0])
    assert m.mean == pytest.approx(2.5)
    assert m.se == pytest.approx(math.sqrt(5 / 3) / 2)
    assert mean_se([7.0]).se == 0.0


def test_wilcoxon_exact_small_sample() -> None:
    # all 5 differences positive: W- = 0, exact two-sided p = 2 / 2^5 = 0.0625
    assert wilcoxon_p([1, 2, 3, 4, 5], [0, 0, 0, 0, 0]) == pytest.approx(0.0625)
    # a zero difference is dropped (zero_method "wilcox"): same p
    assert wilcoxon_p([1, 2, 3, 4, 5, 9], [0, 0, 0, 0, 0, 9]) == pytest.approx(0.0625)
    # ranks 1..4 with signs + + - +: W- = 3, exact two-sided p = 2 * P(W <= 3) = 2 * 5/16
    assert wilcoxon_p([1, 2, -3, 4], [0, 0, 0, 0]) == pytest.approx(0.625)


def test_wilcoxon_degenerate_cases_give_one_not_nan() -> None:
    assert wilcoxon_p([1.0, 2.0], [1.0, 2.0]) == 1.0
    assert math.isfinite(wilcoxon_p([1.0, 2.0], [1.0, 1.0]))


def test_mcnemar_exact_by_hand() -> None:
    a = [True] * 5 + [False] * 3 + [True] * 4
    b = [False] * 5 + [False] * 3 + [True] * 4
    # 5 discordant pairs, all favouring a: p = 2 * 0.5^5
    assert mcnemar_p(a, b) == pytest.approx(0.0625)
    assert mcnemar_p(a, a) == 1.0
    # 3 vs 1 discordant: p = 2 * (1 + 4) / 16 = 0.625
    assert mcnemar_p([True, True, True, False], [False, False, False, True]) == pytest.approx(0.625)


def test_bad_paired_input_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="paired samples"):
        wilcoxon_p([1, 2], [1, 2, 3])
    with pytest.raises(ValueError, match="finite"):
        paired_diff([1.0, float("nan")], [0.0, 0.0])
    with pytest.raises(ValueError, match="paired samples"):
        mcnemar_p([], [])


def test_summarise_cell_by_hand() -> None:
    c = cell("aail", [[-1, -3], [-2, -4], [-3, -5], [-6, -8]], [True, True, False, True])
    s = summarise_cell(c)
    assert s.ego.mean == pytest.approx(-3.0)
    assert s.others.mean == pytest.approx(-5.0)
    assert s.team.mean == pytest.approx(-8.0)
    assert s.ego_success == pytest.approx(0.75)
    assert s.partner_success == 1.0
    assert s.ego_reached == 1.0
    assert s.solved == pytest.approx(0.75)
    assert s.length.mean == pytest.approx(25.0)


def test_compare_cells_pairs_by_episode() -> None:
    a = cell("aail", [[-1, -1], [-2, -2], [-3, -3], [-4, -4]], [True] * 4)
    b = cell("sl", [[-2, -1], [-3, -2], [-4, -3], [-5, -4]], [False] * 4)
    tests = {t.measure: t for t in compare_cells(a, b)}
    assert tests["ego return"].diff.mean == pytest.approx(1.0)
    assert tests["ego return"].diff.se == 0.0
    assert tests["others' return"].p == 1.0
    assert tests["team return"].p == pytest.approx(0.125)  # 4 equal positive differences
    assert tests["ego success"].test == "mcnemar"
    assert tests["ego success"].p == pytest.approx(0.125)
    other = CellResult(**{**vars(b), "scenario": Scenario("t", "a2", ("b3",), 4, 2)})
    with pytest.raises(ValueError, match="scenarios differ"):
        compare_cells(a, other)
