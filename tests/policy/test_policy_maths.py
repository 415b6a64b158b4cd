"""policy.maths: hand-computed values of eqs. 2, 3, 9, 10, input errors and stability properties."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from policy.maths import boltzmann, js_distance, normalized_entropy, soft_value, task_weight

LN2 = math.log(2.0)


# --- hand-computed numbers ------------------------------------------------------------------


@pytest.mark.parametrize("alpha", [0.1, 1.0, 7.0])
def test_soft_value_of_two_actions_is_alpha_log_sum(alpha: float) -> None:
    # Q = [0, α ln 2]: V = α ln(e^0 + e^ln2) = α ln 3
    v = soft_value([0.0, alpha * LN2], alpha)
    assert v == pytest.approx(alpha * math.log(3.0), rel=1e-12)


def test_soft_value_of_equal_actions_adds_alpha_log_a() -> None:
    # Q = [c]*A: V = c + α ln A
    assert soft_value([5.0, 5.0, 5.0, 5.0], 0.5) == pytest.approx(5.0 + 0.5 * math.log(4.0))


def test_soft_value_tends_to_max_as_alpha_vanishes() -> None:
    v = soft_value([[1e6, -1e6, 3.0], [0.0, 1e-3, -2.0]], 1e-9)
    np.testing.assert_allclose(v, [1e6, 1e-3], rtol=1e-12)


def test_soft_value_accepts_per_row_alpha_and_any_batch_shape() -> None:
    q_23A = np.zeros((2, 3, 2))
    v = soft_value(q_23A, np.array([[1.0], [2.0]]))
    np.testing.assert_allclose(v, [[LN2] * 3, [2 * LN2] * 3])


def test_boltzmann_hand_values() -> None:
    # Q = [ln 3, 0], α = 1 -> [3/4, 1/4]; α = 0.5 -> [9/10, 1/10]
    np.testing.assert_allclose(boltzmann([math.log(3.0), 0.0], 1.0), [0.75, 0.25])
    np.testing.assert_allclose(boltzmann([math.log(3.0), 0.0], 0.5), [0.9, 0.1])


def test_boltzmann_with_tiny_alpha_is_one_hot_and_ties_split() -> None:
    np.testing.assert_array_equal(boltzmann([1.0, 2.0, 0.0], 1e-9), [0.0, 1.0, 0.0])
    np.testing.assert_allclose(boltzmann([2.0, 2.0, 0.0], 1e-9), [0.5, 0.5, 0.0])


def test_normalized_entropy_uniform_one_and_one_hot_zero() -> None:
    assert normalized_entropy(np.full(5, 0.2)) == pytest.approx(1.0)
    assert normalized_entropy([0.0, 1.0, 0.0]) == 0.0
    # [1/2, 1/4, 1/4]: H = 1.5 bits, over log2 3 bits
    assert normalized_entropy([0.5, 0.25, 0.25]) == pytest.approx(1.5 / math.log2(3.0))


def test_normalized_entropy_of_one_action_is_zero() -> None:
    np.testing.assert_array_equal(normalized_entropy(np.ones((4, 1))), np.zeros(4))


def test_task_weight_hand_values() -> None:
    assert task_weight(np.full(4, 0.25)) == pytest.approx(0.0, abs=1e-15)
    assert task_weight([0.0, 0.0, 1.0, 0.0]) == pytest.approx(1.0 - 1.0 / 4)
    # [1/2, 1/2, 0, 0]: H_4 = 1/2, 4^(1/2) = 2 effective actions, w_t = 1 - 2/4
    assert task_weight([0.5, 0.5, 0.0, 0.0]) == pytest.approx(0.5)
    assert task_weight([[1.0]]) == np.array([1.0])


def test_js_distance_hand_values() -> None:
    assert js_distance([1.0, 0.0], [0.0, 1.0]) == pytest.approx(1.0)
    assert js_distance([0.3, 0.7], [0.3, 0.7]) == 0.0
    # [3/4, 1/4] vs [1/4, 3/4]: m = [1/2, 1/2], JS = 3/4 log2(3/2) + 1/4 log2(1/2)
    js = 0.75 * math.log2(1.5) - 0.25
    assert js_distance([0.75, 0.25], [0.25, 0.75]) == pytest.approx(math.sqrt(js))
    # [1, 0] vs [1/2, 1/2]: m = [3/4, 1/4]; JS = 1/2 log2(4/3) + 1/2 (1/2 log2(2/3) + 1/2 log2 2)
    js = 0.5 * math.log2(4 / 3) + 0.25 * math.log2(2 / 3) + 0.25
    assert js_distance([1.0, 0.0], [0.5, 0.5]) == pytest.approx(math.sqrt(js))


def test_js_distance_broadcasts_batches() -> None:
    p_1A = np.array([[1.0, 0.0]])
    q_3A = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
    d = js_distance(p_1A[:, None, :], q_3A[None])
    assert d.shape == (1, 3)
    np.testing.assert_allclose(d[0, :2], [0.0, 1.0])


# --- bad input ------------------------------------------------------------------------------


@pytest.mark.parametrize("alpha", [0.0, -1.0, math.nan, math.inf, np.array([1.0, -2.0])])
def test_bad_alpha_is_rejected(alpha: float) -> None:
    with pytest.raises(ValueError, match="alpha"):
        soft_value(np.zeros((2, 3)), alpha)
    with pytest.raises(ValueError, match="alpha"):
        boltzmann(np.zeros((2, 3)), alpha)


def test_alpha_of_wrong_shape_is_rejected() -> None:
    with pytest.raises(ValueError, match=r"alpha: shape \(3,\) .* batch shape \(2,\)"):
        boltzmann(np.zeros((2, 4)), np.ones(3))


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_q_is_rejected(bad: float) -> None:
    with pytest.raises(ValueError, match=r"q_BA: 1 non-finite .* \(2, 2\)"):
        soft_value([[0.0, 1.0], [bad, 0.0]], 1.0)
    with pytest.raises(ValueError, match="q_BA"):
        boltzmann([bad, 0.0], 1.0)


def test_empty_action_axis_is_rejected() -> None:
    with pytest.raises(ValueError, match=r"q_BA: .* at least one action, got shape \(3, 0\)"):
        soft_value(np.zeros((3, 0)), 1.0)
    with pytest.raises(ValueError, match="pi_BA"):
        normalized_entropy(np.zeros((3, 0)))
    with pytest.raises(ValueError, match="q_BA"):
        boltzmann(5.0, 1.0)


def test_bad_probabilities_are_rejected() -> None:
    with pytest.raises(ValueError, match="pi_BA: probabilities must sum to 1"):
        task_weight([0.5, 0.6])
    with pytest.raises(ValueError, match="pi_BA: probabilities must be non-negative"):
        normalized_entropy([1.5, -0.5])
    with pytest.raises(ValueError, match="q_BA: probabilities must sum to 1"):
        js_distance([0.5, 0.5], [0.5, 0.4])
    with pytest.raises(ValueError, match="action axes differ"):
        js_distance([0.5, 0.5], [0.2, 0.3, 0.5])
    with pytest.raises(ValueError, match="p_BA: expected an array of real numbers"):
        js_distance("abc", [1.0])


# --- properties -----------------------------------------------------------------------------

finite_q = st.floats(-1e6, 1e6, allow_nan=False)
alphas = st.floats(1e-6, 1e3)
q_rows = arrays(np.float64, st.tuples(st.integers(1, 4), st.integers(1, 6)), elements=finite_q)


@settings(max_examples=150, deadline=None)
@given(q=q_rows, alpha=alphas)
def test_policy_is_a_finite_distribution_and_weights_are_in_range(
    q: np.ndarray, alpha: float
) -> None:
    pi = boltzmann(q, alpha)
    assert np.isfinite(pi).all() and (pi >= 0).all()
    np.testing.assert_allclose(pi.sum(axis=-1), 1.0, atol=1e-12)
    v = soft_value(q, alpha)
    assert np.isfinite(v).all()
    # max Q ≤ V ≤ max Q + α ln |A| (up to rounding of the large terms)
    slack = 1e-9 * (1.0 + np.abs(q).max(axis=-1))
    assert (v >= q.max(axis=-1) - slack).all()
    assert (v <= q.max(axis=-1) + alpha * math.log(q.shape[-1]) + slack).all()
    h, w = normalized_entropy(pi), task_weight(pi)
    assert ((h >= 0) & (h <= 1)).all()
    assert ((w >= 0) & (w <= 1)).all()
    d = js_distance(pi, pi[::-1])
    assert ((d >= 0) & (d <= 1)).all()
    np.testing.assert_array_equal(js_distance(pi, pi), 0.0)


@settings(max_examples=150, deadline=None)
@given(
    q=arrays(
        np.float64, st.tuples(st.integers(1, 3), st.integers(1, 5)), elements=st.floats(-1e3, 1e3)
    ),
    shift=arrays(np.float64, 3, elements=st.floats(-1e3, 1e3)),
    alpha=st.floats(1e-3, 1e3),
)
def test_policy_entropy_and_jsd_are_invariant_to_a_constant_per_row(
    q: np.ndarray, shift: np.ndarray, alpha: float
) -> None:
    shifted = q + shift[: q.shape[0], None]
    pi, pi_shifted = boltzmann(q, alpha), boltzmann(shifted, alpha)
    np.testing.assert_allclose(pi_shifted, pi, atol=1e-7)
    np.testing.assert_allclose(normalized_entropy(pi_shifted), normalized_entropy(pi), atol=1e-6)
    other = boltzmann(q[::-1], alpha)
    np.testing.assert_allclose(js_distance(pi_shifted, other), js_distance(pi, other), atol=1e-6)
    np.testing.assert_allclose(
        soft_value(shifted, alpha), soft_value(q, alpha) + shift[: q.shape[0]]
    )


def test_extremes_give_no_nan() -> None:
    q = np.array([[1e300, -1e300, 0.0], [1e-300, 0.0, -1e-300], [0.0, 0.0, 0.0]])
    for alpha in (1e-9, 1.0, 1e300):
        pi = boltzmann(q, alpha)
        assert np.isfinite(pi).all()
        np.testing.assert_allclose(pi.sum(axis=-1), 1.0)
        assert np.isfinite(soft_value(q, alpha)).all()
        assert np.isfinite(task_weight(pi)).all() and np.isfinite(js_distance(pi, pi[::-1])).all()
    np.testing.assert_array_equal(boltzmann(q, 1e-9)[0], [1.0, 0.0, 0.0])
