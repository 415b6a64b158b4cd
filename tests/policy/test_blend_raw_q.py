"""AAIL's eq. 8 on raw Q-vectors (`normalise=False`, the kitchen's choice): numbers by hand,
the row path bit for bit against the vectorised path, and the engine following the domain."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from envs.cooking.domain import COOKING
from envs.particle.domain import PARTICLE
from policy.blend import blend, blend_vectorised
from policy.maths import boltzmann, js_distance, task_weight


def test_raw_blend_by_hand() -> None:
    q_task = np.array([[1.0, 2.0, 4.0]])
    q_impact = np.array([[[3.0, 0.0, 0.0], [0.0, 0.0, 6.0]]])
    alpha = 0.5
    got = blend_vectorised("aail", q_task, q_impact, alpha, normalise=False)
    pi_t = boltzmann(q_task, alpha)
    pi_i = boltzmann(q_impact, alpha)
    w_t = task_weight(pi_t)[0]
    w = js_distance(pi_t[:, None, :], pi_i)[0]
    w_hat = w / w.sum()
    expected = w_t * q_task[0] + (1 - w_t) * (w_hat[0] * q_impact[0, 0] + w_hat[1] * q_impact[0, 1])
    np.testing.assert_allclose(got.q_BA[0], expected, rtol=1e-12)
    np.testing.assert_allclose(got.probs_BA[0], boltzmann(expected, alpha), rtol=1e-12)
    np.testing.assert_allclose(got.partner_weights_BP[0], w_hat, rtol=1e-12)
    assert got.task_weight_B[0] == pytest.approx(w_t)


def test_a_nearly_flat_impact_q_no_longer_outvotes_the_task() -> None:
    """The kitchen's deadlock (reports/cooking/README.md): a task Q with a clear best action and
    an impact Q with a spread of 0.2. Standardised, the impact's noise flips the choice."""
    q_task = np.array([[23.88, 17.15, 24.62, 24.21, 22.23]])
    q_impact = np.array([[[11.07, 11.30, 10.92, 11.18, 10.75]]])
    raw = blend("aail", q_task, q_impact, 0.05, normalise=False)
    standardised = blend("aail", q_task, q_impact, 0.05)
    assert raw.probs_BA[0].argmax() == 2 == q_task[0].argmax()
    assert standardised.probs_BA[0].argmax() != 2


def test_no_partner_is_the_task_alone() -> None:
    q_task = np.array([[0.5, 1.5, -1.0]])
    got = blend("aail", q_task, np.zeros((1, 0, 3)), 0.1, normalise=False)
    np.testing.assert_array_equal(got.q_BA, q_task)
    assert got.task_weight_B[0] == 1.0


finite = st.floats(-50, 50, allow_nan=False, allow_subnormal=False)


@settings(max_examples=150, deadline=None)
@given(
    rows=st.integers(1, 4),
    partners=st.integers(0, 3),
    actions=st.integers(2, 6),
    alpha=st.floats(0.01, 5.0),
    data=st.data(),
)
def test_compiled_equals_the_reference_when_raw(rows, partners, actions, alpha, data) -> None:
    def draw(strategy: st.SearchStrategy, size: int) -> np.ndarray:
        return np.array(data.draw(st.lists(strategy, min_size=size, max_size=size)))

    q_task = draw(finite, rows * actions).reshape(rows, actions)
    q_impact = draw(finite, rows * partners * actions).reshape(rows, partners, actions)
    mask = draw(st.booleans(), rows * partners).reshape(rows, partners).astype(bool)
    reference = blend_vectorised("aail", q_task, q_impact, alpha, mask, normalise=False)
    got = blend("aail", q_task, q_impact, alpha, mask, normalise=False)  # compiled where built
    np.testing.assert_allclose(got.q_BA, reference.q_BA, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got.probs_BA, reference.probs_BA, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(
        got.partner_weights_BP, reference.partner_weights_BP, rtol=1e-9, atol=1e-9
    )


def test_each_environment_declares_its_normalisation() -> None:
    assert PARTICLE.blend_normalisation == "standardise"  # the paper evaluation's blend
    assert COOKING.blend_normalisation == "none"
