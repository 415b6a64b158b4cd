"""`policy.regret_budget` (eqs. B1-B4) against a direct, row-by-row reading of the equations."""

from __future__ import annotations

import numpy as np
import pytest

from policy.maths import boltzmann
from policy.regret_budget import budget_rows, initial_budget


def _direct(pi_t, pi_c, q_t, q_i, spent, total, kappa):
    """One row, in plain Python, exactly as the module docstring writes B1-B4."""
    n = len(pi_t)
    cost = sum((pi_t[a] - pi_c[a]) * q_t[a] for a in range(n))  # B1
    gain = sum((pi_c[a] - pi_t[a]) * q_i[p][a] for p in range(len(q_i)) for a in range(n))  # B2
    if cost <= 0:
        beta = 1.0 if gain > 0 else 0.0
    elif gain > kappa * cost:
        beta = min(1.0, max(total - spent, 0.0) / cost)
    else:
        beta = 0.0
    pi = [(1 - beta) * pi_t[a] + beta * pi_c[a] for a in range(n)]  # B3
    return pi, spent + beta * max(cost, 0.0), beta, cost, gain  # B4


@pytest.mark.parametrize("kappa", [0.0, 1.0, 2.5])
def test_budget_rows_equal_the_equations_on_random_rows(kappa: float) -> None:
    rng = np.random.default_rng(7)
    rows, actions = 10_000, 5
    for partners in (0, 1, 3):
        q_t = rng.normal(0, 2, (rows, actions))
        q_i = rng.normal(0, 2, (rows, partners, actions))
        pi_t = boltzmann(q_t, rng.uniform(0.05, 2.0, rows))
        pi_c = boltzmann(q_t + rng.normal(0, 3, (rows, actions)), 0.5)
        total = rng.uniform(0, 1.0, rows)
        spent = total * rng.uniform(0, 1.2, rows)  # some rows over budget already
        step = budget_rows(pi_t, pi_c, q_t, q_i, spent, total, kappa)
        for b in range(0, rows, 7):  # every 7th row: ~1,400 rows per case, 12,800 in all
            pi, s, beta, cost, gain = _direct(
                pi_t[b], pi_c[b], q_t[b], q_i[b], spent[b], total[b], kappa
            )
            np.testing.assert_allclose(step.probs_BA[b], pi, rtol=0, atol=1e-12)
            assert step.spent_B[b] == pytest.approx(s, abs=1e-12)
            assert step.beta_B[b] == pytest.approx(beta, abs=1e-12)
            assert step.cost_B[b] == pytest.approx(cost, abs=1e-9)
            assert step.gain_B[b] == pytest.approx(gain, abs=1e-9)


def test_the_budget_is_never_overspent_and_the_ego_follows_its_task_once_spent() -> None:
    rng = np.random.default_rng(3)
    q_t = rng.normal(0, 1, (2000, 5))
    q_i = rng.normal(0, 1, (2000, 1, 5)) * 5  # partners gain a lot: the budget binds
    pi_t, pi_c = boltzmann(q_t, 0.3), boltzmann(q_i[:, 0], 0.3)
    total = np.full(2000, 0.2)
    spent = np.zeros(2000)
    for _ in range(20):  # an episode of 20 steps on the same states
        step = budget_rows(pi_t, pi_c, q_t, q_i, spent, total)
        assert (step.spent_B <= total + 1e-12).all()
        assert (step.spent_B >= spent).all()
        spent = step.spent_B
    exhausted = np.isclose(spent, total)
    assert exhausted.any()
    last = budget_rows(pi_t, pi_c, q_t, q_i, spent, total)
    costly = exhausted & (last.cost_B > 0)
    np.testing.assert_allclose(last.probs_BA[costly], pi_t[costly], atol=1e-12)


def test_no_partner_or_no_gain_gives_the_task_policy() -> None:
    rng = np.random.default_rng(1)
    q_t = rng.normal(0, 1, (50, 5))
    pi_t, pi_c = boltzmann(q_t, 0.5), boltzmann(-q_t, 0.5)
    step = budget_rows(pi_t, pi_c, q_t, np.zeros((50, 0, 5)), np.zeros(50), np.ones(50))
    np.testing.assert_allclose(step.probs_BA, pi_t, atol=1e-15)
    assert (step.spent_B == 0).all()


def test_initial_budget_is_a_fraction_of_the_expected_task_value() -> None:
    q_t = np.array([[-2.0, -4.0, -6.0]])
    pi_t = boltzmann(q_t, 1.0)
    expected = 0.1 * abs(float((pi_t * q_t).sum()))
    assert initial_budget(pi_t, q_t, 0.1)[0] == pytest.approx(expected)
