"""The paper's four claims turned into checks with fixed thresholds.

The thresholds were fixed before any result was seen and are the same for the hand-picked
scenarios and the pair sample; a claim is *reproduced* when all its checks pass, *not
reproduced* when none does, *partly* otherwise. One check was tightened after the first full
run: "AAIL ≈ NAIL" first asked only for p >= 0.01, which 17 aligned pairs passed with NAIL 35
points worse than AAIL (no power, not similarity). A large p is absence of evidence, not
evidence of similarity, so the check is now an equivalence test: paired TOST on team return with
a margin of 2 % of NAIL's mean (`evaluation.stats.tost_paired`), both one-sided p's printed.

Every p a check reads is Holm-adjusted within its family: the scenario's tests table, every
comparison of `SCENARIO_COMPARISONS` on every measure (`scenario_family`), the same numbers the
report's table prints beside their 95 % t intervals and rank-biserial effect sizes.

| claim | check                                                                  | threshold            |
|-------|------------------------------------------------------------------------|----------------------|
| 1     | AAIL team return > SL's (paired Wilcoxon, Holm-adjusted)               | p < 0.01             |
| 1     | NAIL team return > SL's                                                | p < 0.01             |
| 1     | AAIL ≈ NAIL on team return (the paper: p ~ 0.16): equivalent by paired | both p's < 0.05,     |
|       | TOST within 2 % of NAIL's mean team return                             | margin 2 %           |
| 2     | NAIL ends inside its own target far less often than AAIL (McNemar)     | gap >= 0.25, p < 0.01|
| 2     | AAIL's own-return regret vs SL is small: (SL - AAIL) / abs(SL ego)     | <= 0.25, and < NAIL's|
| 2     | AAIL still reaches its target (ends inside it)                         | rate >= 0.9          |
| 3     | five agents: AAIL team return > SL's (the paper: p = 0.048)            | p < 0.05             |
| 4     | networks to cover all combinations, N = 2..5: AAIL 2|G| < JL |G|^N    | every N              |
| 4     | training cost of that coverage for N = 2 (measured wall time per       | AAIL < JL            |
|       | network, else env transitions per network)                             |                      |

Goal pairs and goal sets beyond the paper's scenarios are judged by `evaluation.targets`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from evaluation.config import METHOD_LABELS
from evaluation.paper.scaling import KindTraining, networks_needed
from evaluation.rollout import CellResult
from evaluation.stats import PairedTest, compare_cells, fmt_p, tost_paired, with_holm

ALPHA_STRONG = 0.01
ALPHA_FIVE = 0.05
SUCCESS_GAP = 0.25
MAX_REGRET = 0.25
MIN_SUCCESS = 0.9
N_GOALS = 35
EQUIVALENCE_MARGIN = 0.02  # TOST margin, a fraction of the reference's mean
ALPHA_EQUIVALENCE = 0.05

# The scenario tables' comparisons: the paper's AAIL against every other method, then the
# other blends and NAIL against SL (each claim's test is one of these); those whose methods did
# not both run are left out.
SCENARIO_COMPARISONS: tuple[tuple[str, str], ...] = (
    ("aail", "sl"),
    ("aail", "nail"),
    ("aail", "aail_bounded"),
    ("aail", "aail_budget"),
    ("aail", "jl"),
    ("aail_bounded", "sl"),
    ("aail_budget", "sl"),
    ("nail", "sl"),
)


@dataclass(frozen=True)
class Check:
    text: str
    passed: bool
    detail: str  # the numbers behind the verdict


@dataclass(frozen=True)
class Claim:
    key: str  # "1", "1 (pairs)", ...
    title: str
    paper: str
    checks: tuple[Check, ...]

    @property
    def verdict(self) -> str:
        if not self.checks:
            return "not tested"
        passed = sum(c.passed for c in self.checks)
        if passed == len(self.checks):
            return "reproduced"
        return "not reproduced" if passed == 0 else "partly reproduced"


def scenario_family(cells: Mapping[str, CellResult]) -> list[PairedTest]:
    """Every comparison of `SCENARIO_COMPARISONS` whose methods both ran, on every measure of
    `compare_cells`, Holm-adjusted together: one scenario table, one family."""
    tests = [
        t
        for method, other in SCENARIO_COMPARISONS
        if method in cells and other in cells
        for t in compare_cells(cells[method], cells[other])
    ]
    return with_holm(tests)


def find_test(tests: Sequence[PairedTest], method: str, other: str, measure: str) -> PairedTest:
    return next(t for t in tests if (t.method, t.other, t.measure) == (method, other, measure))


def describe(t: PairedTest) -> str:
    """`method − other = mean ± SE, 95 % CI [..], r = .. (p = .., Holm p = .., n = ..)`."""
    holm = "" if t.p_holm is None else f", Holm p = {fmt_p(t.p_holm)}"
    return (
        f"{METHOD_LABELS.get(t.method, t.method)} − {METHOD_LABELS.get(t.other, t.other)} = "
        f"{t.diff}, 95 % CI {t.ci}, r = {t.effect:+.2f} (p = {fmt_p(t.p)}{holm}, n = {t.n})"
    )


def _adjusted(t: PairedTest) -> float:
    return t.p if t.p_holm is None else t.p_holm


def _team_gain(family: Sequence[PairedTest], method: str, alpha: float) -> Check:
    test = find_test(family, method, "sl", "team return")
    label = method.upper()
    return Check(
        f"{label} team return > SL (Holm-adjusted p < {alpha:g})",
        test.diff.mean > 0 and _adjusted(test) < alpha,
        describe(test),
    )


def claim_aligned(cells: Mapping[str, CellResult]) -> Claim:
    family = scenario_family(cells)
    checks = [_team_gain(family, "aail", ALPHA_STRONG), _team_gain(family, "nail", ALPHA_STRONG)]
    checks.append(_similar(cells["aail"].team_E, cells["nail"].team_E))
    paper = "AAIL and NAIL beat SL on team return (p < 2e-19); AAIL ≈ NAIL (p ~ 0.16)"
    return Claim("1", "goal-aligned: blending helps the team", paper, tuple(checks))


def _regret(sl_ego: float, ego: float) -> float:
    return (sl_ego - ego) / abs(sl_ego) if sl_ego != 0 else float("inf")


def _non_aligned_checks(
    success: Mapping[str, float],
    ego: Mapping[str, float],
    success_p: float,
    unit: str,
    success_test: str,
) -> tuple[Check, ...]:
    gap = success["aail"] - success["nail"]
    regret_aail = _regret(ego["sl"], ego["aail"])
    regret_nail = _regret(ego["sl"], ego["nail"])
    return (
        Check(
            f"NAIL ends in its own target far less often than AAIL (gap >= {SUCCESS_GAP:g}, "
            f"Holm-adjusted p < {ALPHA_STRONG:g})",
            gap >= SUCCESS_GAP and success_p < ALPHA_STRONG,
            f"success AAIL {success['aail']:.2f}, NAIL {success['nail']:.2f}, SL "
            f"{success['sl']:.2f} (per {unit}; {success_test})",
        ),
        Check(
            f"AAIL's own-return regret vs SL is small (<= {MAX_REGRET:.0%} and below NAIL's)",
            regret_aail <= MAX_REGRET and regret_aail < regret_nail,
            f"ego return SL {ego['sl']:.2f}, AAIL {ego['aail']:.2f}, NAIL {ego['nail']:.2f}: "
            f"regret AAIL {regret_aail:.1%}, NAIL {regret_nail:.1%}",
        ),
        Check(
            f"AAIL still reaches its target (success >= {MIN_SUCCESS:g})",
            success["aail"] >= MIN_SUCCESS,
            f"AAIL ego success {success['aail']:.2f}",
        ),
    )


def claim_non_aligned(cells: Mapping[str, CellResult]) -> Claim:
    success = {m: float(c.success_EN[:, 0].mean()) for m, c in cells.items()}
    ego = {m: float(c.returns_EN[:, 0].mean()) for m, c in cells.items()}
    test = find_test(scenario_family(cells), "aail", "nail", "ego success")
    paper = "only NAIL fails to reach its target; AAIL finishes, slightly behind SL and JL"
    checks = _non_aligned_checks(success, ego, _adjusted(test), "episode, McNemar", describe(test))
    return Claim("2", "non-aligned: action alignment keeps the own task", paper, checks)


def claim_five(cells: Mapping[str, CellResult]) -> Claim:
    paper = "AAIL beats SL on team return (p = 0.048)"
    check = _team_gain(scenario_family(cells), "aail", ALPHA_FIVE)
    return Claim("3", "five agents: AAIL scales beyond two", paper, (check,))


SIMILAR = (
    f"AAIL ≈ NAIL on team return (paired TOST, margin {EQUIVALENCE_MARGIN:.0%} of NAIL's mean, "
    f"both p < {ALPHA_EQUIVALENCE:g})"
)


def _similar(aail_team: np.ndarray, nail_team: np.ndarray) -> Check:
    tost = tost_paired(
        aail_team, nail_team, margin_fraction=EQUIVALENCE_MARGIN, alpha=ALPHA_EQUIVALENCE
    )
    verdict = "equivalent" if tost.equivalent else "not equivalent"
    return Check(SIMILAR, tost.equivalent, f"AAIL − NAIL: {tost.describe()}: {verdict}")


def claim_scaling(costs: Sequence[KindTraining], agents: Sequence[int] = (2, 3, 4, 5)) -> Claim:
    counts = {n: networks_needed(N_GOALS, n) for n in agents}
    fewer = all(c["aail"] < c["jl"] for c in counts.values())
    checks = [
        Check(
            "AAIL needs fewer networks than JL for N = " + ", ".join(map(str, agents)),
            fewer,
            "; ".join(f"N={n}: AAIL {c['aail']}, JL {c['jl']:,}" for n, c in counts.items()),
        )
    ]
    by_kind = {c.kind: c for c in costs}
    if {"task", "impact", "joint"} <= set(by_kind):
        task, impact, joint = by_kind["task"], by_kind["impact"], by_kind["joint"]
        n2 = counts[agents[0]]
        if task.wall and impact.wall and joint.wall:
            unit = "s of wall time"
            aail = N_GOALS * (task.wall.per_network_s + impact.wall.per_network_s)
            jl = n2["jl"] * joint.wall.per_network_s
        else:
            unit = "env transitions"
            aail = N_GOALS * (task.transitions + impact.transitions)
            jl = n2["jl"] * joint.transitions
        checks.append(
            Check(
                f"covering all N = {agents[0]} combinations costs AAIL less than JL",
                aail < jl,
                f"AAIL {aail:,.0f} vs JL {jl:,.0f} {unit} ({jl / aail:,.0f}×)",
            )
        )
    paper = "AAIL: 70 networks for any N; JL: 35^N (52,521,875 for N = 5)"
    return Claim("4", "scaling: networks and training cost", paper, tuple(checks))
