"""The paper's four claims turned into checks with fixed thresholds.

The thresholds were fixed before any result was seen and are the same for the hand-picked
scenarios and the pair sample; a claim is *reproduced* when all its checks pass, *not
reproduced* when none does, *partly* otherwise. One check was tightened after the first full
run: "AAIL ≈ NAIL" first asked only for p >= 0.01, which 17 aligned pairs passed with NAIL 35
points worse than AAIL (no power, not similarity); it now also asks the difference to be no
larger than AAIL's own difference from SL. Tightening can only turn a pass into a fail.

| claim | check                                                                  | threshold            |
|-------|------------------------------------------------------------------------|----------------------|
| 1     | AAIL team return > SL's (paired Wilcoxon)                              | p < 0.01             |
| 1     | NAIL team return > SL's                                                | p < 0.01             |
| 1     | AAIL ≈ NAIL on team return (the paper: p ~ 0.16): not significantly     | p >= 0.01 and        |
|       | different, and the difference no larger than AAIL's difference from SL  | abs(A-N) <= abs(A-SL)|
| 2     | NAIL ends inside its own target far less often than AAIL               | gap >= 0.25, p < 0.01|
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

from evaluation.paper.scaling import KindTraining, networks_needed
from evaluation.rollout import CellResult
from evaluation.stats import compare_cells

ALPHA_STRONG = 0.01
ALPHA_FIVE = 0.05
SUCCESS_GAP = 0.25
MAX_REGRET = 0.25
MIN_SUCCESS = 0.9
N_GOALS = 35


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


def _p(p: float) -> str:
    return f"p = {p:.2g}"


def _team_gain(cells: Mapping[str, CellResult], method: str, alpha: float) -> Check:
    test = next(t for t in compare_cells(cells[method], cells["sl"]) if t.measure == "team return")
    label = method.upper()
    return Check(
        f"{label} team return > SL (p < {alpha:g})",
        test.diff.mean > 0 and test.p < alpha,
        f"{label} − SL = {test.diff} ({_p(test.p)}, n = {test.n})",
    )


def claim_aligned(cells: Mapping[str, CellResult]) -> Claim:
    checks = [_team_gain(cells, "aail", ALPHA_STRONG), _team_gain(cells, "nail", ALPHA_STRONG)]
    test = next(
        t for t in compare_cells(cells["aail"], cells["nail"]) if t.measure == "team return"
    )
    gain = next(t for t in compare_cells(cells["aail"], cells["sl"]) if t.measure == "team return")
    checks.append(_similar(test.diff.mean, test.p, gain.diff.mean, f"AAIL − NAIL = {test.diff}"))
    paper = "AAIL and NAIL beat SL on team return (p < 2e-19); AAIL ≈ NAIL (p ~ 0.16)"
    return Claim("1", "goal-aligned: blending helps the team", paper, tuple(checks))


def _regret(sl_ego: float, ego: float) -> float:
    return (sl_ego - ego) / abs(sl_ego) if sl_ego != 0 else float("inf")


def _non_aligned_checks(
    success: Mapping[str, float], ego: Mapping[str, float], success_p: float, unit: str
) -> tuple[Check, ...]:
    gap = success["aail"] - success["nail"]
    regret_aail = _regret(ego["sl"], ego["aail"])
    regret_nail = _regret(ego["sl"], ego["nail"])
    return (
        Check(
            f"NAIL ends in its own target far less often than AAIL (gap >= {SUCCESS_GAP:g}, "
            f"p < {ALPHA_STRONG:g})",
            gap >= SUCCESS_GAP and success_p < ALPHA_STRONG,
            f"success AAIL {success['aail']:.2f}, NAIL {success['nail']:.2f}, SL "
            f"{success['sl']:.2f} ({_p(success_p)}, per {unit})",
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
    test = next(
        t for t in compare_cells(cells["aail"], cells["nail"]) if t.measure == "ego success"
    )
    paper = "only NAIL fails to reach its target; AAIL finishes, slightly behind SL and JL"
    checks = _non_aligned_checks(success, ego, test.p, "episode, McNemar")
    return Claim("2", "non-aligned: action alignment keeps the own task", paper, checks)


def claim_five(cells: Mapping[str, CellResult]) -> Claim:
    paper = "AAIL beats SL on team return (p = 0.048)"
    return Claim(
        "3", "five agents: AAIL scales beyond two", paper, (_team_gain(cells, "aail", ALPHA_FIVE),)
    )


SIMILAR = f"AAIL ≈ NAIL on team return (p >= {ALPHA_STRONG:g}, abs(A − N) <= abs(A − SL))"


def _similar(diff: float, p: float, gain_over_sl: float, shown: str) -> Check:
    passed = p >= ALPHA_STRONG and abs(diff) <= abs(gain_over_sl)
    return Check(SIMILAR, passed, f"{shown} ({_p(p)}); AAIL − SL = {gain_over_sl:.2f}")


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
