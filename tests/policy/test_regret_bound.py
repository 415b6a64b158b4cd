"""AAIL-B (eq. R1, `policy.regret_bound`) against a direct implementation of its equation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from policy.blend import blend, blend_vectorised
from policy.maths import boltzmann
from policy.regret_bound import bound_rows, check_regret_bound, keep_goal_rows

ALPHA = 0.02


def direct(q_task: list[float], probs_blend: list[float], alpha: float, eps: float) -> list[float]:
    """Eq. R1 written out action by action."""
    best = max(q_task)
    weights = [math.exp((q - best) / alpha) for q in q_task]
    pi_t = [w / sum(weights) for w in weights]
    inside = [a for a, q in enumerate(q_task) if q >= best - eps]
    task_mass = sum(pi_t[a] for a in inside)
    blend_mass = sum(probs_blend[a] for a in inside)
    out = list(pi_t)
    if blend_mass > 0:
        for a in inside:
            out[a] = task_mass * probs_blend[a] / blend_mass
    return out


def _rows(seed: int, n: int = 200) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q_task = rng.normal(size=(n, 5)) * rng.choice([0.01, 0.05, 0.3], size=(n, 1))
    q_impact = rng.normal(size=(n, 2, 5)) * rng.choice([0.02, 0.5], size=(n, 1, 1))
    return q_task, q_impact


@pytest.mark.parametrize("eps", [0.0, 0.01, 0.02, 0.05, 1.0])
def test_blend_matches_the_direct_equation(eps: float) -> None:
    q_task, q_impact = _rows(1)
    aail = blend("aail", q_task, q_impact, ALPHA).probs_BA
    bounded = blend("aail_bounded", q_task, q_impact, ALPHA, regret_bound=eps)
    reference = blend_vectorised("aail_bounded", q_task, q_impact, ALPHA, regret_bound=eps)
    for b in range(len(q_task)):
        expected = direct(q_task[b].tolist(), aail[b].tolist(), ALPHA, eps)
        np.testing.assert_allclose(bounded.probs_BA[b], expected, rtol=0, atol=1e-12)
        row = blend(
            "aail_bounded", q_task[b : b + 1], q_impact[b : b + 1], ALPHA, regret_bound=eps
        )  # one row: the same code, B = 1
        np.testing.assert_allclose(row.probs_BA[0], expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(reference.probs_BA, bounded.probs_BA, rtol=0, atol=1e-12)
    # the diagnostics are AAIL's
    np.testing.assert_allclose(
        bounded.task_weight_B, blend("aail", q_task, q_impact, ALPHA).task_weight_B
    )


def test_the_regret_against_the_task_policy_is_at_most_eps() -> None:
    q_task, q_impact = _rows(2, 500)
    pi_t = boltzmann(q_task, ALPHA)
    for eps in (0.0, 0.005, 0.02, 0.1):
        pi_b = blend("aail_bounded", q_task, q_impact, ALPHA, regret_bound=eps).probs_BA
        regret = (pi_t * q_task).sum(axis=1) - (pi_b * q_task).sum(axis=1)
        assert regret.max() <= eps + 1e-12
        np.testing.assert_allclose(pi_b.sum(axis=1), 1.0, atol=1e-12)


def test_limits_task_policy_and_aail() -> None:
    q_task, q_impact = _rows(3)
    pi_t = boltzmann(q_task, ALPHA)
    tight = blend("aail_bounded", q_task, q_impact, ALPHA, regret_bound=0.0).probs_BA
    np.testing.assert_allclose(tight, pi_t, atol=1e-12)  # random Q: no ties
    loose = blend("aail_bounded", q_task, q_impact, ALPHA, regret_bound=1e6).probs_BA
    np.testing.assert_allclose(loose, blend("aail", q_task, q_impact, ALPHA).probs_BA, atol=1e-12)


def test_outside_actions_keep_their_task_probability_by_hand() -> None:
    # task: right best, rest 0.07 below (outside ε = 0.02), up 0.01 below (inside)
    q_task = np.array([[-0.07, -0.01, -0.8, -0.26, 0.0]])
    probs_blend = np.array([[0.9, 0.05, 0.0, 0.0, 0.05]])  # the blend wants to rest
    pi_t = boltzmann(q_task, ALPHA)
    out = bound_rows(probs_blend, q_task, pi_t, 0.02)[0]
    assert out[0] == pytest.approx(pi_t[0, 0])  # rest keeps its small task probability
    inside = pi_t[0, 1] + pi_t[0, 4]
    assert out[1] == pytest.approx(inside * 0.5) and out[4] == pytest.approx(inside * 0.5)


def test_no_blend_mass_inside_falls_back_to_the_task_policy() -> None:
    q_task = np.array([[0.0, -1.0, -1.0]])
    probs_task = boltzmann(q_task, ALPHA)
    got = bound_rows(np.array([[0.0, 0.5, 0.5]]), q_task, probs_task, 0.1)
    np.testing.assert_allclose(got, probs_task, rtol=0, atol=1e-15)


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf"), "0.1", True, None])
def test_bad_regret_bounds_name_the_field(bad: object) -> None:
    with pytest.raises(ValueError, match="regret_bound"):
        check_regret_bound(bad)  # type: ignore[arg-type]
    if bad is None:
        return
    with pytest.raises(ValueError, match="regret_bound"):
        blend("aail_bounded", np.zeros((1, 3)), np.zeros((1, 1, 3)), ALPHA, regret_bound=bad)  # type: ignore[arg-type]


def test_regret_bound_belongs_to_aail_bounded_only() -> None:
    with pytest.raises(ValueError, match="regret_bound: required for method aail_bounded"):
        blend("aail_bounded", np.zeros((1, 3)), np.zeros((1, 1, 3)), ALPHA)
    with pytest.raises(ValueError, match="regret_bound: applies to method aail_bounded only"):
        blend("aail", np.zeros((1, 3)), np.zeros((1, 1, 3)), ALPHA, regret_bound=0.1)


def test_one_bound_per_row() -> None:
    """The progress guard passes ε per row (0 where the ego's own goal is not reached)."""
    q_task, q_impact = _rows(4, 6)
    eps_B = np.array([0.0, 0.02, 0.0, 0.05, 1.0, 0.01])
    rows = blend("aail_bounded", q_task, q_impact, ALPHA, regret_bound=eps_B).probs_BA
    for b, eps in enumerate(eps_B):
        one = blend("aail_bounded", q_task[b : b + 1], q_impact[b : b + 1], ALPHA, regret_bound=eps)
        np.testing.assert_allclose(rows[b], one.probs_BA[0], atol=1e-15)
    with pytest.raises(ValueError, match="regret_bound: expected one number or 6"):
        blend("aail_bounded", q_task, q_impact, ALPHA, regret_bound=eps_B[:3])
    with pytest.raises(ValueError, match="regret_bound"):
        blend("aail_bounded", q_task, q_impact, ALPHA, regret_bound=-eps_B)


def keep_direct(probs: list[float], kept: list[bool]) -> list[float]:
    """Eq. R4 written out action by action."""
    mass = sum(p for p, k in zip(probs, kept, strict=True) if k)
    if all(kept) or not any(kept) or mass == 0:
        return probs
    return [p / mass if k else 0.0 for p, k in zip(probs, kept, strict=True)]


def test_keep_goal_matches_the_direct_equation() -> None:
    rng = np.random.default_rng(9)
    probs = rng.dirichlet(np.ones(5), size=300)
    probs[:20, :2] = 0.0  # rows whose kept actions may carry no probability
    probs[:20] /= probs[:20].sum(axis=1, keepdims=True)
    kept = rng.random((300, 5)) < rng.choice([0.0, 0.4, 0.8, 1.0], size=(300, 1))
    kept[:20] = [True, True, False, False, False]
    rows = keep_goal_rows(probs, kept)
    for p, k, got in zip(probs, kept, rows, strict=True):
        want = keep_direct(p.tolist(), k.tolist())
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
        one = keep_goal_rows(p[None], k[None])[0]  # one row: the same code, B = 1
        np.testing.assert_allclose(one, want, rtol=1e-12)
        assert got.sum() == pytest.approx(1.0)
    one = keep_goal_rows(np.array([[0.2, 0.3, 0.5]]), np.array([[True, False, True]]))
    np.testing.assert_allclose(one, [[0.2 / 0.7, 0.0, 0.5 / 0.7]], rtol=1e-15)
