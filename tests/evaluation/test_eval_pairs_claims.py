"""Pair-sample aggregation and the claim checks on hand-made results."""

from __future__ import annotations

import numpy as np
import pytest

from evaluation.claims import (
    Check,
    Claim,
    claim_aligned,
    claim_five,
    claim_non_aligned,
    claim_non_aligned_pairs,
    claim_scaling,
)
from evaluation.config import Scenario
from evaluation.pairs import pair_groups, pair_means, pair_test
from evaluation.rollout import CellResult
from evaluation.scaling import KindTraining


def cell(scenario: Scenario, method: str, ego: list[float], other: list[float],
         success: list[bool] | None = None) -> CellResult:  # fmt: skip
    n = len(ego)
    success = [True] * n if success is None else success
    return CellResult(
        scenario=scenario,
        method=method,
        returns_EN=np.stack([ego, other], axis=1).astype(float),
        success_EN=np.stack([success, [True] * n], axis=1),
        reached_EN=np.ones((n, 2), dtype=bool),
        length_E=np.full(n, 10),
        solved_E=np.array(success),
        trajectory_TN4=np.zeros((1, 2, 4)),
    )


ALIGNED = Scenario("pair:c+c4", "c", ("c4",), 2, 1)  # is_aligned
OTHER = Scenario("pair:a2+b3", "a2", ("b3",), 2, 2)  # not aligned


def test_pair_means_and_groups_by_hand() -> None:
    results = [
        cell(ALIGNED, "aail", [-1, -3], [-2, -2]),
        cell(ALIGNED, "sl", [-2, -2], [-6, -4]),
        cell(OTHER, "aail", [-5, -5], [-1, -1], [True, False]),
        cell(OTHER, "sl", [-4, -4], [-3, -3]),
    ]
    means = {p.scenario.name: p for p in pair_means(results)}
    assert means["pair:c+c4"].by_method["aail"] == {
        "ego": -2.0, "others": -2.0, "team": -4.0, "ego_success": 1.0, "length": 10.0,
    }  # fmt: skip
    assert means["pair:a2+b3"].by_method["aail"]["ego_success"] == 0.5
    groups = {g.label: g for g in pair_groups(results)}
    assert set(groups) == {"aligned", "non-aligned"}
    aligned = groups["aligned"]
    assert aligned.means["sl"]["team"].mean == pytest.approx(-7.0)
    test = aligned.test("aail", "sl", "team")
    assert test is not None and test.diff.mean == pytest.approx(3.0) and test.better == 1.0
    assert pair_test(aligned.pairs, "aail", "jl", "team") is None  # no pair ran JL


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
    assert not similar.passed
    assert "p = 0.062" in similar.detail and "AAIL − SL = 0.99" in similar.detail


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


def test_claim_non_aligned_on_pairs_and_five_agents() -> None:
    results = []
    for k in range(8):
        s = Scenario(f"pair:{k}", "a2", ("b3",), 2, k)  # 8 pairs: exact p = 2 / 2^8
        results += [
            cell(s, "sl", [-10.0 - k] * 2, [-5.0] * 2),
            cell(s, "aail", [-10.5 - k] * 2, [-4.0] * 2),
            cell(s, "nail", [-30.0 - k] * 2, [-3.0] * 2, [False, False]),
        ]
    [group] = pair_groups(results)
    assert group.label == "non-aligned"
    assert claim_non_aligned_pairs(group).verdict == "reproduced"
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
