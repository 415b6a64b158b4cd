"""`policy.regret_budget` (eqs. B1-B4) against a direct, row-by-row reading of the equations."""

from __future__ import annotations

import numpy as np
import pytest

from policy.maths import boltzmann, soft_value
from policy.regret_budget import budget_rows, initial_budget


def _direct(pi_t, pi_c, q_t, value, spent, total, last_value):
    """One row, in plain Python, exactly as the module docstring writes B1-B4."""
    n = len(pi_t)
    cost = sum((pi_t[a] - pi_c[a]) * q_t[a] for a in range(n))  # B1
    if spent >= total:  # B4: spent for good
        return list(pi_t), spent, False, cost
    charged = max(0.0, spent + last_value - value)  # B2
    if charged < total:  # B3
        return list(pi_c), max(0.0, charged + cost), True, cost
    return list(pi_t), charged, False, cost


def test_budget_rows_equal_the_equations_on_random_rows() -> None:
    rng = np.random.default_rng(7)
    rows, actions = 10_000, 5
    q_t = rng.normal(0, 2, (rows, actions))
    alpha = rng.uniform(0.05, 2.0, rows)
    pi_t = boltzmann(q_t, alpha)
    pi_c = boltzmann(q_t + rng.normal(0, 3, (rows, actions)), 0.5)
    value = soft_value(q_t, alpha)
    last_value = value + rng.normal(0, 0.5, rows)  # rose, fell or stayed since the last step
    last_value[::5] = value[::5]
    total = rng.uniform(0, 1.0, rows)
    spent = total * rng.uniform(0, 1.2, rows)  # some rows over budget already
    spent[::11] = 0.0
    step = budget_rows(pi_t, pi_c, q_t, value, spent, total, last_value)
    for b in range(0, rows, 3):
        pi, s, blended, cost = _direct(
            pi_t[b], pi_c[b], q_t[b], value[b], spent[b], total[b], last_value[b]
        )
        np.testing.assert_allclose(step.probs_BA[b], pi, rtol=0, atol=1e-15)
        assert step.spent_B[b] == pytest.approx(s, abs=1e-12)
        assert bool(step.blend_B[b]) is blended
        assert step.cost_B[b] == pytest.approx(cost, abs=1e-9)
    assert 0 < step.blend_B.mean() < 1  # both branches of B3 (and B4) were exercised


def test_a_spent_budget_stays_spent_and_the_ego_follows_its_task() -> None:
    """Once S reaches B the rows follow π_t for good, whatever their value does after (B4)."""
    rng = np.random.default_rng(3)
    rows = 2000
    total = np.full(rows, 0.5)
    spent, value = np.zeros(rows), np.zeros(rows)
    stopped = np.zeros(rows, dtype=bool)
    for _ in range(30):  # an episode whose value wanders
        q_t = rng.normal(0, 0.1, (rows, 5))
        pi_t = boltzmann(q_t, 0.3)
        pi_c = boltzmann(q_t + rng.normal(0, 0.1, (rows, 5)), 0.3)
        new_value = value + rng.normal(-0.005, 0.05, rows)
        step = budget_rows(pi_t, pi_c, q_t, new_value, spent, total, value)
        np.testing.assert_allclose(step.probs_BA[stopped], pi_t[stopped], atol=0)
        assert not step.blend_B[stopped].any()
        assert (step.spent_B >= 0).all()
        stopped |= ~step.blend_B
        spent, value = step.spent_B, new_value
    assert 0 < stopped.mean() < 1


def test_a_rising_value_pays_back_a_drop_but_never_into_credit() -> None:
    """B2 is Page's CUSUM: S falls with a rising value and stops at 0."""
    pi = np.full((1, 3), 1 / 3)
    q = np.zeros((1, 3))  # π_C = π_t here: c = 0, only the value moves S
    total = np.array([1.0])
    spent = np.zeros(1)
    values = [0.0, -0.3, -0.5, -0.1, 0.4, 0.2]
    want = [0.0, 0.3, 0.5, 0.1, 0.0, 0.2]
    last = np.array([values[0]])
    for v, w in zip(values, want, strict=True):
        step = budget_rows(pi, pi, q, np.array([v]), spent, total, last)
        assert step.spent_B[0] == pytest.approx(w)
        spent, last = step.spent_B, np.array([v])


def test_identical_policies_cost_nothing() -> None:
    rng = np.random.default_rng(1)
    q_t = rng.normal(0, 1, (50, 5))
    pi_t = boltzmann(q_t, 0.5)
    value = soft_value(q_t, 0.5)
    step = budget_rows(pi_t, pi_t, q_t, value, np.zeros(50), np.ones(50), value)
    np.testing.assert_allclose(step.probs_BA, pi_t, atol=0)
    np.testing.assert_allclose(step.cost_B, 0.0, atol=1e-12)
    assert (step.spent_B < 1e-12).all()


def test_initial_budget_is_the_same_for_every_row() -> None:
    np.testing.assert_array_equal(initial_budget(0.16, 3), [0.16, 0.16, 0.16])
