"""Statistics helpers against hand-computed numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as sps

from evaluation.config import Scenario
from evaluation.rollout import CellResult
from evaluation.stats import (
    cohens_dz,
    compare_cells,
    holm,
    mcnemar_p,
    mean_se,
    paired_ci,
    paired_diff,
    rank_biserial,
    summarise_cell,
    tost_paired,
    tost_verdict,
    wilcoxon_p,
    with_holm,
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
    # every difference +1: the interval has no width, every pair favours a (r = 1)
    ego = tests["ego return"]
    assert (ego.ci.low, ego.ci.high, ego.effect) == (1.0, 1.0, 1.0)
    assert tests["others' return"].effect == 0.0  # no pair differs
    assert tests["ego success"].effect == 1.0 and tests["length"].effect == 0.0
    assert all(t.p_holm is None for t in tests.values())  # not adjusted until a family is named
    other = CellResult(**{**vars(b), "scenario": Scenario("t", "a2", ("b3",), 4, 2)})
    with pytest.raises(ValueError, match="scenarios differ"):
        compare_cells(a, other)


def test_paired_ci_by_hand_and_against_scipy() -> None:
    # d = 1, 2, 3, 4: mean 2.5, se = sqrt(5/3) / 2 = 0.645497, t_{0.975, 3} = 3.182446
    ci = paired_ci([1, 2, 3, 4], [0, 0, 0, 0])
    assert ci.level == 0.95
    assert ci.low == pytest.approx(2.5 - 3.182446 * 0.645497, abs=1e-5)
    assert ci.high == pytest.approx(2.5 + 3.182446 * 0.645497, abs=1e-5)
    rng = np.random.default_rng(3)
    a, b = rng.normal(1, 2, 40), rng.normal(0, 2, 40)
    want = sps.ttest_rel(a, b).confidence_interval(0.9)
    got = paired_ci(a, b, level=0.9)
    assert (got.low, got.high) == pytest.approx((want.low, want.high), rel=1e-10)
    assert str(paired_ci([1, 1], [0, 0])) == "[1.00, 1.00]"  # no spread, no width
    single = paired_ci([1.0], [0.0])
    assert single.low == -math.inf and single.high == math.inf
    with pytest.raises(ValueError, match="level"):
        paired_ci([1, 2], [0, 0], level=1.5)


def test_rank_biserial_by_hand_and_against_scipy() -> None:
    # ranks 1..4 of |d| with signs + + - +: W+ = 7, W- = 3, r = 4 / 10
    assert rank_biserial([1, 2, -3, 4], [0, 0, 0, 0]) == pytest.approx(0.4)
    # |d| = 1, 1, 2 tied at ranks 1.5, 1.5, 3: W+ = 3 = W-
    assert rank_biserial([1, 1, -2], [0, 0, 0]) == pytest.approx(0.0)
    # 0/±1 differences: (b - c) / (b + c) over the discordant pairs, the zero dropped
    assert rank_biserial([1, 1, 1, 0, 1], [0, 0, 0, 1, 1]) == pytest.approx((3 - 1) / (3 + 1))
    assert rank_biserial([2, 3], [2, 3]) == 0.0
    assert rank_biserial([0, 0], [1, 5]) == -1.0
    rng = np.random.default_rng(4)
    a, b = rng.normal(0.3, 1, 25), rng.normal(0, 1, 25)
    w_plus = float(sps.wilcoxon(a, b, alternative="greater").statistic)  # the sum of + ranks
    assert rank_biserial(a, b) == pytest.approx(2 * w_plus / (25 * 26 / 2) - 1, rel=1e-12)


def test_cohens_dz_by_hand_and_against_scipy() -> None:
    assert cohens_dz([1, 2, 3, 4], [0, 0, 0, 0]) == pytest.approx(2.5 / math.sqrt(5 / 3))
    rng = np.random.default_rng(5)
    a, b = rng.normal(0.5, 1, 30), rng.normal(0, 1, 30)
    t = float(sps.ttest_rel(a, b).statistic)
    assert cohens_dz(a, b) == pytest.approx(t / math.sqrt(30), rel=1e-12)
    assert cohens_dz([1, 1], [1, 1]) == 0.0
    assert cohens_dz([2, 2], [1, 1]) == math.inf
    assert math.isnan(cohens_dz([2], [1]))


def test_holm_by_hand() -> None:
    # sorted 0.005, 0.01, 0.03, 0.04 scaled by 4, 3, 2, 1: 0.02, 0.03, 0.06, 0.04 -> running max
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm([0.5, 0.6]) == [1.0, 1.0]  # capped at 1 and never below a smaller p's
    assert holm([0.02, 0.02]) == pytest.approx([0.04, 0.04])
    assert holm([0.3]) == [0.3] and holm([]) == []
    for bad in ([1.2], [float("nan")], [-0.1]):
        with pytest.raises(ValueError, match="p_values"):
            holm(bad)


def test_with_holm_adjusts_one_family() -> None:
    a = cell("aail", [[-1, -1], [-2, -2], [-3, -3], [-4, -4]], [True] * 4)
    b = cell("sl", [[-2, -1], [-3, -2], [-4, -3], [-5, -4]], [False] * 4)
    tests = compare_cells(a, b)
    adjusted = with_holm(tests)
    assert [t.p_holm for t in adjusted] == pytest.approx(holm([t.p for t in tests]))
    assert [t.p for t in adjusted] == [t.p for t in tests]
    # 5 tests; the smallest p (0.125, three times) is scaled by 5, capped at 1
    assert min(t.p_holm or 0 for t in adjusted) == pytest.approx(0.625)


def test_tost_by_hand() -> None:
    # d = 1, 2, 3 against a reference of mean -100: δ = 2 % of 100 = 2; d̄ = 2, se = 1 / sqrt(3)
    # p⁻ = P(T_2 >= 4 sqrt(3)) = (1 - t / sqrt(t² + 2)) / 2 at t² = 48: (1 - sqrt(48 / 50)) / 2
    # p⁺ = P(T_2 <= 0) = 0.5
    b = [-100.0, -100.0, -100.0]
    tost = tost_paired([-99.0, -98.0, -97.0], b, margin_fraction=0.02)
    assert tost.margin == pytest.approx(2.0) and tost.reference == pytest.approx(-100.0)
    assert tost.p_lower == pytest.approx((1 - math.sqrt(48 / 50)) / 2)
    assert tost.p_upper == pytest.approx(0.5)
    assert tost.verdict == "not worse" and tost.not_worse and not tost.equivalent
    # the 90 % interval the two tests invert: d̄ ± t_{0.95, 2} se, t_{0.95, 2} = 2.919986
    assert tost.ci.level == pytest.approx(0.9)
    assert tost.ci.low == pytest.approx(2 - 2.919986 / math.sqrt(3), abs=1e-5)
    assert tost.ci.low > -tost.margin
    text = tost.describe(p_lower=0.02)
    assert "margin ±2.00 (2% of |-100.00|)" in text and "Holm-adjusted 0.02" in text


def test_tost_against_scipy_one_sided_t_tests() -> None:
    rng = np.random.default_rng(6)
    b = rng.normal(-10, 1, 50)
    a = b + rng.normal(0.05, 0.2, 50)
    tost = tost_paired(a, b, margin_fraction=0.02)
    d, delta = a - b, 0.02 * abs(b.mean())
    assert tost.p_lower == pytest.approx(sps.ttest_1samp(d, -delta, alternative="greater").pvalue)
    assert tost.p_upper == pytest.approx(sps.ttest_1samp(d, delta, alternative="less").pvalue)
    assert tost.verdict == "equivalent"  # d̄ ~ 0.05 ± 0.03 well inside ±0.2
    worse = tost_paired(b - 1.0 + rng.normal(0, 0.2, 50), b)
    assert worse.verdict == "not shown" and worse.p_lower > 0.5
    # a large p of an ordinary test is not equivalence: 3 noisy pairs show nothing
    noisy = tost_paired([-10.0, -7.0, -13.0], [-10.0, -10.0, -10.0])
    assert wilcoxon_p([-10.0, -7.0, -13.0], [-10.0] * 3) == 1.0 and noisy.verdict == "not shown"


def test_tost_degenerate_and_bad_input() -> None:
    same = tost_paired([1.0, 2.0], [1.0, 2.0])  # every difference 0, inside any margin
    assert (same.p_lower, same.p_upper, same.verdict) == (0.0, 0.0, "equivalent")
    better = tost_paired([5.0, 6.0], [1.0, 2.0])  # +4 everywhere, beyond a 2 % margin
    assert (better.p_lower, better.p_upper, better.verdict) == (0.0, 1.0, "not worse")
    one = tost_paired([5.0], [1.0])
    assert (one.p_lower, one.p_upper, one.verdict) == (1.0, 1.0, "not shown")
    with pytest.raises(ValueError, match="margin_fraction"):
        tost_paired([1.0, 2.0], [1.0, 2.0], margin_fraction=-0.1)
    with pytest.raises(ValueError, match="margin_fraction"):
        tost_paired([1.0, 2.0], [1.0, 2.0], margin_fraction=float("inf"))
    with pytest.raises(ValueError, match="alpha"):
        tost_paired([1.0, 2.0], [1.0, 2.0], alpha=0.5)
    with pytest.raises(ValueError, match="paired samples"):
        tost_paired([1.0, 2.0], [1.0])
    assert tost_verdict(0.01, 0.01) == "equivalent"
    assert tost_verdict(0.01, 0.2) == "not worse"
    assert tost_verdict(0.2, 0.01) == "not shown"
