"""Statistics of paired samples: tests, intervals, effect sizes, equivalence, multiplicity.

| function          | what                                                                    |
|-------------------|-------------------------------------------------------------------------|
| `mean_se`         | mean and standard error (sample std / sqrt(n)) — `services.env_client`'s|
| `wilcoxon_p`      | two-sided Wilcoxon signed-rank p of paired samples (scipy); 1 when every|
|                   | difference is 0 (nothing to rank), NaN-free                             |
| `mcnemar_p`       | two-sided exact McNemar p of paired successes (binomial test on the     |
|                   | discordant pairs); 1 when there are none                                |
| `paired_diff`     | mean ± SE of the paired differences a - b                               |
| `paired_ci`       | t confidence interval of the mean paired difference (95 % by default)   |
| `rank_biserial`   | matched-pairs rank-biserial correlation of a - b, in [-1, 1]: the       |
|                   | effect size that goes with the Wilcoxon signed-rank test               |
| `cohens_dz`       | Cohen's d_z of a - b: mean / sample std of the differences              |
| `tost_paired`     | paired TOST equivalence test, margin a fraction of the reference mean   |
| `tost_verdict`    | "equivalent" / "not worse" / "not shown" from the two one-sided p's     |
| `holm`            | Holm's step-down adjusted p-values of one family of tests               |
| `with_holm`       | the same tests with `p_holm` set, the given tests being the family      |
| `summarise_cell`  | one method's row of a scenario table                                    |
| `compare_cells`   | AAIL (or any method) against another on the same episodes               |

Success is binary, so its paired test is McNemar's, not Wilcoxon's (a signed-rank test on 0/±1
differences is a sign test with a normal approximation); every other measure uses Wilcoxon with
scipy's defaults (zero differences dropped, exact distribution for small samples without ties).

Beside every p: the 95 % interval of the mean difference is Student's t interval of the paired
differences, d̄ ± t_{0.975, n-1} s_d / sqrt(n) (for success, a difference of 0/±1 values: the Wald
interval of a paired difference of proportions with a t quantile); the effect size is the
matched-pairs rank-biserial correlation r = (W+ - W-) / (W+ + W-), the signed-rank sums over the
non-zero differences that Wilcoxon's test ranks, so r and p always speak of the same differences
(on 0/±1 differences r = (b - c) / (b + c) over McNemar's discordant counts b and c).

Equivalence ("not worse", "the same") is never judged from a large p: `tost_paired` runs Schuirmann's
two one-sided paired t tests against a margin δ = fraction × |mean of the reference| (H0⁻: mean
difference <= -δ, H0⁺: mean difference >= +δ). Rejecting H0⁻ alone shows *not worse* (by more than
δ: non-inferiority), rejecting both shows *equivalent*; the (1 - 2α) t interval lying above -δ, or
inside (-δ, δ), says the same.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar, cast

import numpy as np
from scipy import stats as sps

from evaluation.rollout import CellResult
from services.env_client import MeanSE, mean_se

__all__ = [
    "CI_LEVEL",
    "Interval",
    "MeanSE",
    "MethodSummary",
    "PairedTest",
    "Tost",
    "cohens_dz",
    "compare_cells",
    "fmt_p",
    "holm",
    "mcnemar_p",
    "mean_se",
    "paired_ci",
    "paired_diff",
    "rank_biserial",
    "summarise_cell",
    "tost_paired",
    "tost_verdict",
    "wilcoxon_p",
    "with_holm",
]

CI_LEVEL = 0.95


def _paired(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> np.ndarray:
    a_n, b_n = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a_n.ndim != 1 or a_n.shape != b_n.shape or a_n.size == 0:
        raise ValueError(
            f"paired samples: expected two 1-d arrays of one non-zero length, got shapes "
            f"{a_n.shape} and {b_n.shape}"
        )
    if not (np.isfinite(a_n).all() and np.isfinite(b_n).all()):
        raise ValueError("paired samples: expected finite values")
    return a_n - b_n


def wilcoxon_p(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> float:
    """Two-sided Wilcoxon signed-rank p-value of the paired samples a and b."""
    diff = _paired(a, b)
    if not np.any(diff != 0.0):
        return 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # one non-zero difference: se = 0
        p = float(sps.wilcoxon(diff).pvalue)
    return p if math.isfinite(p) else 1.0


def mcnemar_p(a: Sequence[bool] | np.ndarray, b: Sequence[bool] | np.ndarray) -> float:
    """Two-sided exact McNemar p-value of paired binary outcomes a and b."""
    a_n, b_n = np.asarray(a, dtype=bool), np.asarray(b, dtype=bool)
    _paired(a_n.astype(float), b_n.astype(float))
    only_a = int(np.sum(a_n & ~b_n))
    only_b = int(np.sum(~a_n & b_n))
    if only_a + only_b == 0:
        return 1.0
    return float(sps.binomtest(only_a, only_a + only_b, 0.5).pvalue)


def paired_diff(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> MeanSE:
    """Mean ± standard error of the paired differences a - b."""
    return mean_se(_paired(a, b).tolist())


@dataclass(frozen=True)
class Interval:
    """A confidence interval [low, high] at `level` (infinite when one sample cannot give one)."""

    low: float
    high: float
    level: float

    def __str__(self) -> str:
        return f"[{self.low:.2f}, {self.high:.2f}]"

    def __contains__(self, value: float) -> bool:
        return self.low <= value <= self.high


def _t_interval(diff: np.ndarray, level: float) -> Interval:
    n, mean = diff.size, float(diff.mean())
    if n < 2:
        return Interval(-math.inf, math.inf, level)  # one difference has no spread to scale by
    se = float(diff.std(ddof=1)) / math.sqrt(n)
    half = float(sps.t.ppf(0.5 + level / 2, n - 1)) * se
    return Interval(mean - half, mean + half, level)


def _check_level(name: str, value: float, high: float = 1.0) -> None:
    if not (isinstance(value, int | float) and 0.0 < value < high):
        raise ValueError(f"{name}: expected a number in (0, {high:g}), got {value!r}")


def paired_ci(
    a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray, level: float = CI_LEVEL
) -> Interval:
    """Student's t interval of the mean paired difference a - b at `level`:
    d̄ ± t_{(1 + level) / 2, n - 1} · s_d / sqrt(n); [-inf, inf] for a single pair, [d̄, d̄] when
    every difference is the same."""
    _check_level("level", level)
    return _t_interval(_paired(a, b), level)


def rank_biserial(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> float:
    """Matched-pairs rank-biserial correlation of a - b: (W+ - W-) / (W+ + W-), W± the sums of the
    ranks of |a - b| (average ranks for ties) over the positive / negative differences, zero
    differences dropped as `wilcoxon_p` drops them. +1: a above b in every pair that differs;
    0 when no pair differs."""
    diff = _paired(a, b)
    diff = diff[diff != 0.0]
    if diff.size == 0:
        return 0.0
    ranks = sps.rankdata(np.abs(diff))
    w_plus, w_minus = float(ranks[diff > 0].sum()), float(ranks[diff < 0].sum())
    return (w_plus - w_minus) / (w_plus + w_minus)


def cohens_dz(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> float:
    """Cohen's d_z of paired samples: mean(a - b) / std(a - b, ddof=1) (= t / sqrt(n) of the
    paired t test). NaN for a single pair; 0 when every difference is 0; ±inf when every
    difference is the same non-zero value."""
    diff = _paired(a, b)
    if diff.size < 2:
        return math.nan
    mean, sd = float(diff.mean()), float(diff.std(ddof=1))
    if sd == 0.0:
        return 0.0 if mean == 0.0 else math.copysign(math.inf, mean)
    return mean / sd


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values of one family, in the order given: with p_(1) <= ... <=
    p_(m), adjusted p_(k) = max over j <= k of min(1, (m - j + 1) p_(j)). Rejecting where the
    adjusted p < α controls the family-wise error rate at α."""
    ps = np.asarray(p_values, dtype=np.float64)
    if ps.ndim != 1 or not (np.isfinite(ps).all() and ((ps >= 0) & (ps <= 1)).all()):
        raise ValueError(f"p_values: expected a list of numbers in [0, 1], got {list(p_values)}")
    m = ps.size
    order = np.argsort(ps, kind="stable")
    scaled = np.minimum(1.0, (m - np.arange(m)) * ps[order])
    adjusted = np.empty(m)
    adjusted[order] = np.maximum.accumulate(scaled)
    return adjusted.tolist()


class _Tested(Protocol):
    @property
    def p(self) -> float: ...


TestT = TypeVar("TestT", bound=_Tested)


def with_holm(tests: Sequence[TestT]) -> list[TestT]:
    """The tests (dataclasses with `p` and `p_holm` fields) with `p_holm` set to Holm's adjusted p,
    the given tests being one family."""
    adjusted = holm([t.p for t in tests])
    # `replace` wants a dataclass type; the protocol can only promise the `p` it reads
    return [
        cast(TestT, dataclasses.replace(cast(Any, t), p_holm=q))
        for t, q in zip(tests, adjusted, strict=True)
    ]


def tost_verdict(p_lower: float, p_upper: float, alpha: float = 0.05) -> str:
    """ "equivalent" when both one-sided nulls are rejected, "not worse" when only H0⁻ (the first
    is worse by δ or more) is, else "not shown"."""
    if p_lower < alpha and p_upper < alpha:
        return "equivalent"
    return "not worse" if p_lower < alpha else "not shown"


@dataclass(frozen=True)
class Tost:
    """Schuirmann's two one-sided paired t tests of a - b against the margin ±`margin`."""

    n: int
    diff: MeanSE  # mean ± SE of a - b
    reference: float  # mean of b
    margin_fraction: float
    margin: float  # δ = margin_fraction × |reference|
    p_lower: float  # H0⁻: mean(a - b) <= -δ (rejected: a not worse than b by δ or more)
    p_upper: float  # H0⁺: mean(a - b) >= +δ (rejected: a not better than b by δ or more)
    alpha: float
    ci: Interval  # the (1 - 2α) t interval that the two tests invert

    @property
    def verdict(self) -> str:
        return tost_verdict(self.p_lower, self.p_upper, self.alpha)

    @property
    def not_worse(self) -> bool:
        return self.p_lower < self.alpha

    @property
    def equivalent(self) -> bool:
        return self.verdict == "equivalent"

    def describe(self, p_lower: float | None = None) -> str:
        """The test in words; `p_lower` replaces the raw H0⁻ p (e.g. by its Holm-adjusted value)."""
        holm_note = "" if p_lower is None else f" (Holm-adjusted {fmt_p(p_lower)})"
        return (
            f"TOST margin ±{self.margin:.2f} ({self.margin_fraction:.0%} of |{self.reference:.2f}|): "
            f"Δ = {self.diff}, {1 - 2 * self.alpha:.0%} CI {self.ci}, p⁻ = {fmt_p(self.p_lower)}"
            f"{holm_note}, p⁺ = {fmt_p(self.p_upper)}, n = {self.n}"
        )


def fmt_p(p: float) -> str:
    """A p-value as the reports print it: two significant digits, scientific below 0.001."""
    return f"{p:.2g}" if p >= 1e-3 else f"{p:.1e}"


def tost_paired(
    a: Sequence[float] | np.ndarray,
    b: Sequence[float] | np.ndarray,
    *,
    margin_fraction: float = 0.02,
    alpha: float = 0.05,
) -> Tost:
    """Paired TOST of a against the reference b with margin δ = margin_fraction × |mean(b)|.

    p⁻ = P(T_{n-1} >= (d̄ + δ) / se), p⁺ = P(T_{n-1} <= (d̄ - δ) / se), se = s_d / sqrt(n). When
    every difference is the same (se = 0, n >= 2) each p is 0 or 1 (the limit of the t test); a
    single pair can show nothing (both p = 1)."""
    if not (isinstance(margin_fraction, int | float) and math.isfinite(margin_fraction)):
        raise ValueError(f"margin_fraction: expected a finite number >= 0, got {margin_fraction!r}")
    if margin_fraction < 0:
        raise ValueError(f"margin_fraction: expected a finite number >= 0, got {margin_fraction!r}")
    _check_level("alpha", alpha, 0.5)
    diff = _paired(a, b)
    n, mean = diff.size, float(diff.mean())
    reference = float(np.mean(np.asarray(b, dtype=np.float64)))
    margin = margin_fraction * abs(reference)
    se = float(diff.std(ddof=1)) / math.sqrt(n) if n > 1 else 0.0
    if n < 2:
        p_lower = p_upper = 1.0
    elif se == 0.0:
        p_lower = 0.0 if mean > -margin else 1.0
        p_upper = 0.0 if mean < margin else 1.0
    else:
        p_lower = float(sps.t.sf((mean + margin) / se, n - 1))
        p_upper = float(sps.t.cdf((mean - margin) / se, n - 1))
    return Tost(
        n=n,
        diff=MeanSE(mean, se),
        reference=reference,
        margin_fraction=float(margin_fraction),
        margin=margin,
        p_lower=p_lower,
        p_upper=p_upper,
        alpha=float(alpha),
        ci=_t_interval(diff, 1 - 2 * alpha),
    )


@dataclass(frozen=True)
class MethodSummary:
    """One method in one scenario: means ± SE over its episodes."""

    method: str
    episodes: int
    ego: MeanSE  # the controlled agent's return
    others: MeanSE  # the sum of the partners' returns
    per_partner: tuple[MeanSE, ...]
    team: MeanSE  # the sum over every agent
    ego_success: float  # share of episodes ending with the ego inside its target
    ego_reached: float  # share in which the ego was inside its target at some step
    partner_success: float  # share of (episode, partner) ending inside the partner's target
    solved: float  # share ended by termination (all agents inside at one step)
    length: MeanSE


def summarise_cell(result: CellResult) -> MethodSummary:
    returns = result.returns_EN
    return MethodSummary(
        method=result.method,
        episodes=int(returns.shape[0]),
        ego=mean_se(returns[:, 0].tolist()),
        others=mean_se(returns[:, 1:].sum(axis=1).tolist()),
        per_partner=tuple(mean_se(returns[:, j].tolist()) for j in range(1, returns.shape[1])),
        team=mean_se(result.team_E.tolist()),
        ego_success=float(result.success_EN[:, 0].mean()),
        ego_reached=float(result.reached_EN[:, 0].mean()),
        partner_success=float(result.success_EN[:, 1:].mean()),
        solved=float(result.solved_E.mean()),
        length=mean_se(result.length_E.astype(float).tolist()),
    )


@dataclass(frozen=True)
class PairedTest:
    """`method` against `other` on one measure over the same n paired units."""

    measure: str
    method: str
    other: str
    n: int
    diff: MeanSE  # mean of (method - other)
    p: float
    test: str  # "wilcoxon" or "mcnemar"
    ci: Interval  # 95 % t interval of the mean difference
    effect: float  # matched-pairs rank-biserial correlation of (method - other)
    p_holm: float | None = None  # Holm-adjusted within its family (`with_holm`), once adjusted


def compare_cells(a: CellResult, b: CellResult) -> list[PairedTest]:
    """Paired tests of a against b (same scenario, same episodes) on every measure."""
    if a.scenario != b.scenario:
        raise ValueError(f"compare_cells: scenarios differ ({a.scenario.name}, {b.scenario.name})")
    measures = {
        "ego return": (a.returns_EN[:, 0], b.returns_EN[:, 0]),
        "others' return": (a.returns_EN[:, 1:].sum(axis=1), b.returns_EN[:, 1:].sum(axis=1)),
        "team return": (a.team_E, b.team_E),
        "length": (a.length_E.astype(float), b.length_E.astype(float)),
    }
    n = int(a.returns_EN.shape[0])
    tests = [
        PairedTest(
            name,
            a.method,
            b.method,
            n,
            paired_diff(x, y),
            wilcoxon_p(x, y),
            "wilcoxon",
            paired_ci(x, y),
            rank_biserial(x, y),
        )
        for name, (x, y) in measures.items()
    ]
    success_a, success_b = a.success_EN[:, 0], b.success_EN[:, 0]
    x, y = success_a.astype(float), success_b.astype(float)
    tests.append(
        PairedTest(
            "ego success",
            a.method,
            b.method,
            n,
            paired_diff(x, y),
            mcnemar_p(success_a, success_b),
            "mcnemar",
            paired_ci(x, y),
            rank_biserial(x, y),
        )
    )
    return tests
