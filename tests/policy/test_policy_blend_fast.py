"""policy.blend_fast: the plain-Python row blend against the vectorised numpy path of
policy.blend, on random and on ill-conditioned inputs, and the pairwise sum it relies on."""

from __future__ import annotations

import importlib
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from policy.blend import FAST_AAIL_WORK, BlendMethod, blend, blend_vectorised
from policy.blend_fast import blend_row, np_sum

FIELDS = ("probs_BA", "task_entropy_B", "task_weight_B", "partner_weights_BP")
TOL = 1e-9


def _by_rows(method, q_task, q_impact, alpha, mask) -> SimpleNamespace:
    """`blend_row` on every row, shaped like a BlendResult."""
    alphas = np.broadcast_to(alpha, q_task.shape[:1])
    rows = [
        blend_row(
            method, q_task[b].tolist(), q_impact[b].tolist(), float(alphas[b]), mask[b].tolist()
        )
        for b in range(len(q_task))
    ]
    return SimpleNamespace(
        q_BA=np.array([r.q_A for r in rows]),
        probs_BA=np.array([r.probs_A for r in rows]),
        task_entropy_B=np.array([r.task_entropy for r in rows]),
        task_weight_B=np.array([r.task_weight for r in rows]),
        partner_weights_BP=np.array([r.partner_weights_P for r in rows]).reshape(mask.shape),
    )


def _assert_same(fast, reference) -> None:
    """probs and diagnostics within 1e-9; the blended Q within 1e-9 relative."""
    for field in FIELDS:
        np.testing.assert_allclose(
            getattr(fast, field), getattr(reference, field), rtol=TOL, atol=TOL, err_msg=field
        )
    np.testing.assert_allclose(fast.q_BA, reference.q_BA, rtol=TOL, atol=0, err_msg="q_BA")


@st.composite
def cases(draw, max_rows: int = 8):
    """Q-vectors with the degenerate structure the maths must survive: copies of the task
    vector (Σw = 0), near copies (JS distance made of rounding), flat and nearly flat
    vectors, huge and tiny magnitudes; masks; a scalar or per-row temperature."""
    n_rows = draw(st.integers(1, max_rows))
    n_slots = draw(st.integers(0, 8))
    n_act = draw(st.integers(1, 12))
    exponent = draw(st.sampled_from([-300, -12, 0, 0, 3, 300]))
    elems = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
    q_task = draw(arrays(np.float64, (n_rows, n_act), elements=elems)) * 10.0**exponent
    q_impact = draw(arrays(np.float64, (n_rows, n_slots, n_act), elements=elems)) * 10.0**exponent
    shape = draw(st.sampled_from(["random", "copies", "near copies", "flat", "near flat"]))
    if shape == "copies":
        q_impact[:] = q_task[:, None, :]
    elif shape == "near copies":  # their JS distances to the task policy are mostly rounding
        nudge = draw(st.sampled_from([1e-13, 1e-11, 1e-9]))
        q_impact[:] = q_task[:, None, :] * (1 + nudge * np.arange(1, n_slots + 1))[:, None]
    elif shape == "flat":
        q_task[:] = q_task[:, :1]
    elif shape == "near flat":
        q_task[:] = 1.0 + 1e-11 * q_task / (np.abs(q_task).max() or 1.0)
    mask = draw(arrays(np.bool_, (n_rows, n_slots)))
    alpha: float | np.ndarray = draw(st.sampled_from([1e-300, 1e-9, 0.02, 1.0, 1e6]))
    if draw(st.booleans()):
        alpha = draw(arrays(np.float64, (n_rows,), elements=st.floats(1e-3, 10.0)))
    return q_task, q_impact, mask, alpha


@settings(max_examples=300, deadline=None)
@given(case=cases(), method=st.sampled_from(["sl", "nail", "aail"]))
def test_fast_path_equals_the_vectorised_path(case, method: str) -> None:
    q_task, q_impact, mask, alpha = case
    _assert_same(
        _by_rows(method, q_task, q_impact, alpha, mask),
        blend_vectorised(method, q_task, q_impact, alpha, mask),  # type: ignore[arg-type]
    )


@settings(max_examples=150, deadline=None)
@given(case=cases(), method=st.sampled_from(["sl", "nail", "aail"]))
def test_fast_path_is_bit_identical(case, method: str) -> None:
    """The design goal behind the 1e-9 contract: the same operations in the same order give
    the same bits, even where rounding dominates (near copies, nearly flat vectors). Should a
    numpy release change its summation order, this flags it; the contract is the test above."""
    q_task, q_impact, mask, alpha = case
    fast = _by_rows(method, q_task, q_impact, alpha, mask)
    reference = blend_vectorised(method, q_task, q_impact, alpha, mask)  # type: ignore[arg-type]
    for field in (*FIELDS, "q_BA"):
        np.testing.assert_array_equal(getattr(fast, field), getattr(reference, field), field)


@settings(max_examples=100, deadline=None)
@given(case=cases(max_rows=1), method=st.sampled_from(["sl", "nail", "aail"]))
def test_blend_row_on_lists_equals_the_vectorised_path(case, method: str) -> None:
    q_task, q_impact, mask, alpha = case
    alpha = float(np.asarray(alpha).ravel()[0])
    row = blend_row(method, q_task[0].tolist(), q_impact[0].tolist(), alpha, mask[0].tolist())  # type: ignore[arg-type]
    reference = blend_vectorised(method, q_task, q_impact, alpha, mask)  # type: ignore[arg-type]
    np.testing.assert_allclose(row.probs_A, reference.probs_BA[0], rtol=TOL, atol=TOL)
    np.testing.assert_allclose(row.q_A, reference.q_BA[0], rtol=TOL, atol=0)
    assert row.task_entropy == pytest.approx(reference.task_entropy_B[0], rel=TOL, abs=TOL)
    assert row.task_weight == pytest.approx(reference.task_weight_B[0], rel=TOL, abs=TOL)
    np.testing.assert_allclose(
        row.partner_weights_P, reference.partner_weights_BP[0], rtol=TOL, atol=TOL
    )
    assert all(isinstance(p, float) for p in row.probs_A)


def test_masked_slots_are_never_read() -> None:
    q_task = [[0.0, 1.0, 3.0]]
    q_impact = [[[np.nan, 0.0, np.inf], [2.0, 0.0, 1.0]]]
    row = blend_row("aail", q_task[0], q_impact[0], 0.5, [False, True])
    assert row.partner_weights_P == [0.0, 1.0]
    reference = blend_vectorised("aail", q_task, np.nan_to_num(q_impact), 0.5, [[False, True]])
    np.testing.assert_allclose(row.probs_A, reference.probs_BA[0], rtol=TOL, atol=TOL)


def test_edge_cases_by_hand() -> None:
    q = [0.0, 1.0, 2.0]
    # Σw = 0: every impact policy equals the task policy -> equal shares, the task's policy
    same = blend_row("aail", q, [q, q], 1.0)
    assert same.partner_weights_P == [0.5, 0.5]
    np.testing.assert_allclose(same.probs_A, blend_row("sl", q, [], 1.0).probs_A, rtol=1e-15)
    # no partner: w_t = 1 and Q_C = Q_t - mean, the SL policy
    alone = blend_row("aail", q, [], 1.0)
    assert alone.task_weight == 1.0 and alone.q_A == pytest.approx([-1.0, 0.0, 1.0])
    # one action: certain policy, zero entropy, w_t = 1 by definition
    one = blend_row("aail", [5.0], [[2.0]], 1e-9)
    assert (one.probs_A, one.task_entropy, one.task_weight) == ([1.0], 0.0, 1.0)
    # a flat impact vector has z = 0 and scale 0: Q_C = (w_t s_t)(w_t z_t) = w_t² (Q_t - mean)
    flat = blend_row("aail", q, [[7.0, 7.0, 7.0]], 1.0)
    w_t = flat.task_weight
    assert flat.partner_weights_P == [1.0] and 0 < w_t < 1
    assert flat.q_A == pytest.approx([w_t**2 * x for x in [-1.0, 0.0, 1.0]], rel=1e-12)
    # huge Q and a tiny temperature give a one-hot policy without overflow or NaN
    huge = blend_row("aail", [1e300, -1e300, 0.0], [[-1e300, 1e300, 0.0]], 1e-300)
    assert all(np.isfinite(huge.q_A)) and sorted(huge.probs_A) == [0.0, 0.0, 1.0]


def test_js_distance_with_an_underflowed_mixture() -> None:
    """p = 5e-324 against q = 0: m = (p + q) / 2 rounds to 0; numpy then divides by 0 (inf
    bits, distance 1) and the fast path must do the same, without raising."""
    q_task = np.array([[0.0, -745.0 - 0.13]])  # exp gives the smallest subnormal for action 1
    q_impact = np.array([[[0.0, -1e6]]])
    with np.errstate(divide="ignore"):
        reference = blend_vectorised("aail", q_task, q_impact, 1.0)
    row = blend_row("aail", q_task[0].tolist(), q_impact[0].tolist(), 1.0)
    assert row.partner_weights_P == reference.partner_weights_BP[0].tolist()
    np.testing.assert_allclose(row.probs_A, reference.probs_BA[0], rtol=TOL, atol=TOL)


def test_blend_takes_rows_or_the_vectorised_path_by_size(monkeypatch) -> None:
    """Without the compiled blend (tests/policy/test_blend_row_compiled.py covers it)."""
    blend_module = importlib.import_module("policy.blend")  # `policy.blend` is the function
    monkeypatch.setattr(importlib.import_module("policy.blend_fast"), "COMPILED", False)
    taken: list[int] = []
    row = blend_module.blend_row

    def spy(*args, **kwargs):
        taken.append(1)
        return row(*args, **kwargs)

    monkeypatch.setattr(blend_module, "blend_row", spy)
    rng = np.random.default_rng(0)
    cases: list[tuple[BlendMethod, int, int, bool]] = [
        ("aail", 1, 4, True),
        ("aail", FAST_AAIL_WORK // 6 + 1, 4, False),
        ("sl", 2, 8, True),
        ("nail", 3, 1, False),
    ]
    for method, n_rows, n_slots, rows_expected in cases:
        q_task, q_impact = rng.normal(size=(n_rows, 5)), rng.normal(size=(n_rows, n_slots, 5))
        taken.clear()
        _assert_same(
            blend(method, q_task, q_impact, 0.1), blend_vectorised(method, q_task, q_impact, 0.1)
        )
        assert bool(taken) == rows_expected, (method, n_rows, n_slots)
    empty = blend("aail", np.zeros((0, 3)), np.zeros((0, 2, 3)), 1.0)
    assert empty.probs_BA.shape == (0, 3) and empty.partner_weights_BP.shape == (0, 2)


@settings(max_examples=200, deadline=None)
@given(
    values=st.lists(
        st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False) | st.sampled_from([1e-9, 1e9]),
        min_size=0,
        max_size=300,
    )
)
def test_np_sum_adds_in_numpys_order(values: list[float]) -> None:
    """Bit for bit: the pairwise order (blocks of 8 accumulators, halves above 128)."""
    assert np_sum(values) == float(np.sum(np.array(values, dtype=np.float64)))
