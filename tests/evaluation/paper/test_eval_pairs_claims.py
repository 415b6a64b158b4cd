"""Goal-pair aggregation, the paper's claims and the product's targets on hand-made results."""

from __future__ import annotations

import numpy as np
import pytest

from evaluation.config import Scenario
from evaluation.paper.claims import (
    Check,
    Claim,
    claim_aligned,
    claim_five,
    claim_non_aligned,
    claim_scaling,
    scenario_family,
)
from evaluation.paper.pairs import pair_groups, unit_test, units_of
from evaluation.paper.scaling import KindTraining
from evaluation.rollout import CellResult
from evaluation.stats import fmt_p, holm
from evaluation.targets import targets_of


def cell(
    scenario: Scenario,
    method: str,
    ego: list[float],
    other: list[float],
    success: list[bool] | None = None,
    reached: list[bool] | None = None,
) -> CellResult:
    n = len(ego)
    success = [True] * n if success is None else success
    reached = [True] * n if reached is None else reached
    return CellResult(
        scenario=scenario,
        method=method,
        returns_EN=np.stack([ego, other], axis=1).astype(float),
        success_EN=np.stack([success, [True] * n], axis=1),
        reached_EN=np.stack([reached, [True] * n], axis=1),
        length_E=np.full(n, 10),
        solved_E=np.array(success),
        trajectory_TN4=np.zeros((1, 2, 4)),
    )


ALIGNED = Scenario("pair:c+c4", "c", ("c4",), 2, 1)  # influence c0 inside column c
OTHER = Scenario("pair:a2+b3", "a2", ("b3",), 2, 2)  # influence d1, far from a2


def test_units_groups_and_stuck_episodes_by_hand() -> None:
    results = [
        cell(ALIGNED, "aail", [-1, -3], [-2, -2]),
        cell(ALIGNED, "sl", [-2, -2], [-6, -4]),
        # one episode never reached the target, one left it and did not come back
        cell(
            OTHER,
            "aail",
            [-5, -5, -5, -5],
            [-1] * 4,
            [True, False, False, True],
            reached=[True, False, True, True],
        ),
        cell(OTHER, "sl", [-4] * 4, [-3] * 4),
        # a second replicate of the same pair pools into one unit
        cell(Scenario("pair:a2+b3#1", "a2", ("b3",), 2, 1002, 1), "aail", [-7, -7], [-1, -1]),
        cell(Scenario("pair:a2+b3#1", "a2", ("b3",), 2, 1002, 1), "sl", [-4, -4], [-3, -3]),
    ]
    units = {u.combo: u for u in units_of(results)}
    aligned = units["c+c4"]
    assert aligned.by_method["aail"] == {
        "ego": -2.0,
        "others": -2.0,
        "team": -4.0,
        "ego_success": 1.0,
        "stuck": 0.0,
        "never": 0.0,
        "length": 10.0,
    }
    other = units["a2+b3"]
    assert other.episodes == 6 and len(other.scenarios) == 2
    assert other.stuck_episodes == {"aail": 2, "sl": 0}
    assert other.by_method["aail"]["never"] == pytest.approx(1 / 6)
    assert other.regret("aail") == pytest.approx((-4 - (-17 / 3)) / 4)
    groups = pair_groups(results)
    assert set(groups) == {"aligned", "room_to_help", "non_aligned"}
    group = groups["aligned"]
    assert group.rows["sl"].means["team"].mean == pytest.approx(-7.0)
    test = group.test("aail", "sl", "team")
    assert test is not None and test.diff.mean == pytest.approx(3.0) and test.better == 1.0
    assert unit_test(group.units, "aail", "jl", "team") is None  # no pair ran JL
    row = groups["non_aligned"].rows["aail"]
    assert (row.stuck_episodes, row.units_with_stuck, row.episodes) == (2, 1, 6)
    assert groups["non_aligned"].worst("aail")[0].combo == "a2+b3"


def test_verdict_counts_checks() -> None:
    yes, no = Check("a", True, ""), Check("b", False, "")
    assert Claim("1", "t", "", (yes, yes)).verdict == "reproduced"
    assert Claim("1", "t", "", (yes, no)).verdict == "partly reproduced"
    assert Claim("1", "t", "", (no,)).verdict == "not reproduced"
    assert Claim("1", "t", "", ()).verdict == "not tested"


def scenario_cells(
    scenario: Scenario, team_gain: dict[str, float], n: int = 30
) -> dict[str, CellResult]:
    rng = np.random.default_rng(0)
    base = -20 + rng.normal(0, 1, n)
    out = {}
    for method, gain in team_gain.items():
        jitter = rng.normal(0, 0.05, n)
        out[method] = cell(scenario, method, list(base), list(base + gain + jitter))
    return out


def test_claim_aligned_reproduced_when_blending_helps_and_methods_agree() -> None:
    cells = scenario_cells(ALIGNED, {"sl": 0.0, "nail": 3.0, "aail": 3.0})
    claim = claim_aligned(cells)
    assert [c.passed for c in claim.checks] == [True, True, True]
    cells = scenario_cells(ALIGNED, {"sl": 0.0, "nail": 3.0, "aail": -1.0})
    assert [c.passed for c in claim_aligned(cells).checks] == [False, True, False]


def test_similarity_needs_more_than_a_missing_p_value() -> None:
    # 5 episodes: NAIL 30 worse than AAIL is not significant (exact p = 0.0625), yet not similar
    cells = scenario_cells(ALIGNED, {"sl": 0.0, "nail": -30.0, "aail": 1.0}, n=5)
    similar = claim_aligned(cells).checks[2]
    family = {(t.method, t.other, t.measure): t for t in scenario_family(cells)}
    assert family[("aail", "nail", "team return")].p == pytest.approx(0.0625)
    assert not similar.passed
    # the TOST: margin 2 % of NAIL's mean team return (-69.96), AAIL better by 31: p⁺ = 1
    assert "margin ±1.40 (2% of |-69.96|)" in similar.detail and "p⁺ = 1," in similar.detail
    assert similar.detail.endswith(": not equivalent")
    # close means without the evidence are not similar either: 3 noisy episodes
    noisy = {
        m: cell(ALIGNED, m, [-20.0] * 3, [-20.0 + g for g in gains])
        for m, gains in (
            ("sl", [0.0, 0.0, 0.0]),
            ("nail", [0.0, 0.0, 0.0]),
            ("aail", [3.0, -3.5, 0.4]),
        )
    }
    assert not claim_aligned(noisy).checks[2].passed


def test_claim_checks_read_holm_adjusted_p_and_show_interval_and_effect() -> None:
    cells = scenario_cells(ALIGNED, {"sl": 0.0, "nail": 3.0, "aail": 3.0})
    family = scenario_family(cells)
    # sl, nail, aail ran: AAIL − SL, AAIL − NAIL, NAIL − SL on 5 measures each
    assert len(family) == 15
    assert [t.p_holm for t in family] == pytest.approx(holm([t.p for t in family]))
    gain = next(
        t for t in family if (t.method, t.other, t.measure) == ("aail", "sl", "team return")
    )
    check = claim_aligned(cells).checks[0]
    assert "Holm-adjusted" in check.text
    assert f"95 % CI {gain.ci}" in check.detail and f"r = {gain.effect:+.2f}" in check.detail
    assert f"Holm p = {fmt_p(gain.p_holm or 0)}" in check.detail


def test_claim_non_aligned_thresholds() -> None:
    n = 20
    sl = cell(OTHER, "sl", [-10.0] * n, [-5.0] * n)
    aail = cell(OTHER, "aail", [-11.0] * n, [-4.0] * n)  # regret 10 %
    nail = cell(OTHER, "nail", [-30.0] * n, [-3.0] * n, [False] * n)
    claim = claim_non_aligned({"sl": sl, "aail": aail, "nail": nail})
    assert claim.verdict == "reproduced", claim
    aail_bad = cell(OTHER, "aail", [-14.0] * n, [-4.0] * n, [True] * 15 + [False] * 5)
    claim = claim_non_aligned({"sl": sl, "aail": aail_bad, "nail": nail})
    # regret 40 % > 25 %, success 0.75 < 0.9; the gap 0.75 is still >= 0.25
    assert [c.passed for c in claim.checks] == [True, False, False]


NON_ALIGNED = [
    ("a2", "b3"),
    ("a0", "e4"),
    ("a1", "d1"),
    ("b0", "e2"),
    ("a4", "d0"),
    ("a3", "e0"),
    ("b4", "e3"),
    ("a0", "d4"),
    ("b1", "d0"),
    ("a2", "e4"),
]


def test_targets_on_pairs() -> None:
    results = []
    for k, (ego, partner) in enumerate(NON_ALIGNED):
        s = Scenario(f"pair:{ego}+{partner}", ego, (partner,), 2, k)
        results += [
            cell(s, "sl", [-10.0 - k] * 2, [-5.0] * 2),
            cell(s, "aail_bounded", [-10.5 - k] * 2, [-4.0] * 2),  # regret ~4 %, team +0.5
            cell(s, "aail", [-10.0 - k] * 2, [-5.0] * 2, [k != 3, True]),  # one stuck episode
            cell(s, "nail", [-30.0 - k] * 2, [-3.0] * 2, [False, False]),
        ]
    aligned = [("c", "c4"), ("2", "c2"), ("b", "d0"), ("c", "c")]  # the last: I = T
    for k, (ego, partner) in enumerate(aligned):
        s = Scenario(f"pair:{ego}+{partner}", ego, (partner,), 2, 50 + k)
        gain = 0.0 if partner == "c" else 1.0
        results += [
            cell(s, "sl", [-5.0] * 2, [-5.0] * 2),
            cell(s, "aail_bounded", [-5.0] * 2, [-5.0 + gain] * 2),
            cell(s, "aail", [-5.0] * 2, [-5.5] * 2),  # 10 % below SL's team return
        ]
    groups = pair_groups(results)
    assert len(groups["room_to_help"].units) == 3
    targets = {(t.key, t.method): t for t in targets_of(groups, ("aail_bounded", "aail"))}
    non_aligned = targets[("T1", "aail_bounded")]
    assert non_aligned.verdict == "met", non_aligned
    failed = [c.text for c in targets[("T1", "aail")].checks if not c.passed]
    assert failed == ["AAIL ego success >= 0.99", "no stuck episode"]
    # 3 room-to-help pairs cannot reach p < 0.01 (exact Wilcoxon: 0.25); the 2 % share holds
    t2 = targets[("T2", "aail_bounded")]
    assert [c.passed for c in t2.checks] == [True, False] and "3 pairs" in t2.checks[1].detail
    assert [c.passed for c in targets[("T2", "aail")].checks] == [False, False]


def test_five_agent_target_needs_every_set() -> None:
    goals = [("a0", "b2", "c4", "e1"), ("b2", "c4", "e1", "a0"), ("d", "1", "c4", "e1")]
    sets = [Scenario(f"set:{k}", "a2", goals[k], 2, 600 + k) for k in range(3)]
    results = []
    for k, s in enumerate(sets):
        results += [
            cell(s, "sl", [-5.0] * 2, [-20.0] * 2),
            cell(s, "aail_bounded", [-5.0] * 2, [-20.0 + (0.5 if k else -0.1)] * 2),
        ]
    [target] = targets_of(pair_groups(results), ("aail_bounded",))
    assert target.key == "T3" and target.verdict == "not met"
    assert "below SL in 1 of 3 sets (worst -0.10)" in target.checks[0].detail


def test_claim_five_agents() -> None:
    five = Scenario("five_agents", "a2", ("a0", "b2", "c4", "e1"), 2, 3)
    cells = scenario_cells(five, {"sl": 0.0, "aail": 2.0, "nail": 1.0})
    for c in cells.values():  # a 2-column stand-in for the five agents is enough here
        c.scenario = five
    assert claim_five(cells).verdict == "reproduced"


def test_claim_scaling_counts_and_costs() -> None:
    claim = claim_scaling([])
    assert claim.checks[0].passed
    assert "N=5: AAIL 70, JL 52,521,875" in claim.checks[0].detail
    costs = [KindTraining(k, 35, 1000, 16000, 950, "128-128", None) for k in ("task", "impact")]
    costs.append(KindTraining("joint", 3, 1000, 16000, 950, "128-128", None))
    claim = claim_scaling(costs)
    # AAIL 35 * (16000 + 16000) = 1,120,000; JL 1225 * 16000 = 19,600,000 transitions
    assert claim.checks[1].passed
    assert "1,120,000 vs JL 19,600,000 env transitions" in claim.checks[1].detail


def test_not_below_sl_needs_evidence_not_a_large_p() -> None:
    """T1's "team return not below SL's" is a TOST: noisy pairs whose mean difference is inside
    the margin but whose interval is not do not pass, though the old rule (p >= 0.05) did."""
    pairs = [
        Scenario(f"pair:{ego}+{partner}", ego, (partner,), 2, k)
        for k, (ego, partner) in enumerate(NON_ALIGNED)
    ]
    pairs = [s for s in pairs if s.pair_class == "non_aligned"]
    noise = np.random.default_rng(7).normal(0.0, 3.0, len(pairs))
    noise -= noise.mean()  # a mean difference of 0 over the pairs, far from significant
    results = []
    for k, s in enumerate(pairs):
        results += [
            cell(s, "sl", [-10.0] * 2, [-5.0] * 2),
            cell(s, "aail_bounded", [-10.0] * 2, [-5.0 + noise[k]] * 2),
            cell(s, "aail", [-10.0] * 2, [-4.9] * 2),  # +0.1 in every pair: shown not worse
        ]
    groups = pair_groups(results)
    team = groups["non_aligned"].test("aail_bounded", "sl", "team")
    # the old rule (mean >= 0 or p >= 0.05) would have called this "not below"
    assert team is not None and team.p >= 0.05 and abs(team.diff.mean) < 0.3
    targets = {(t.key, t.method): t for t in targets_of(groups, ("aail_bounded", "aail"))}
    noisy = targets[("T1", "aail_bounded")].checks[3]
    assert noisy.text.startswith("team return not below SL's (TOST, margin 2% of SL's")
    assert not noisy.passed and noisy.detail.endswith(": not shown")
    # the margin: 2 % of SL's mean team return, -15 per pair
    assert "margin ±0.30 (2% of |-15.00|)" in noisy.detail
    # Holm over the two methods judged: the raw p⁻ is adjusted, and printed beside the raw one
    tosts = [groups["non_aligned"].tost(m, "sl", "team", 0.02) for m in ("aail_bounded", "aail")]
    raw = [t.p_lower for t in tosts if t is not None]
    assert len(raw) == 2 and raw[1] == 0.0  # +0.1 in every pair
    assert f"p⁻ = {fmt_p(raw[0])} (Holm-adjusted {fmt_p(holm(raw)[0])})" in noisy.detail
    shown = targets[("T1", "aail")].checks[3]
    assert shown.passed and shown.detail.endswith(": not worse")
