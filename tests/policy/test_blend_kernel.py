"""`policy.blend_kernel` (numba), `policy.blend.blend`'s kernel, against `blend_vectorised`, the
numpy reference: every field within 1e-9 on 10,000 random rows per method, one at a time and
in batches (probabilities, entropies, weights absolute and
relative, the blended Q relative) on random, copied, flat, huge and tiny inputs; on
ill-conditioned inputs (near copies, nearly flat task vectors), where the JS distances or the
z-scores are made of rounding and neither implementation's digits mean anything, the
well-conditioned fields within 1e-9 and valid distributions; hand-computed edge cases; bad
shapes refused. aail_bounded's bound (eq. R1, the kernel's last step) against
`regret_bound.bound_rows` on the kernel's own blend, within 1e-9."""

from __future__ import annotations

import importlib
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

blend_module = importlib.import_module("policy.blend")  # `policy.blend` is also the function
blend, blend_vectorised = blend_module.blend, blend_module.blend_vectorised
maths = importlib.import_module("policy.maths")
boltzmann, js_distance = maths.boltzmann, maths.js_distance
bound_rows = importlib.import_module("policy.regret_bound").bound_rows

FIELDS = ("probs_BA", "task_entropy_B", "task_weight_B", "partner_weights_BP")
TOL = 1e-9
METHODS = ("sl", "nail", "aail", "aail_bounded")


def _assert_close(got, want, alpha=None, fields=FIELDS, q: bool = True, scale=None) -> None:
    """Every field within `TOL`; except, with `alpha`, the policy of a row whose blended Q
    differs by more than `TOL` α (ties at a tiny temperature: Boltzmann is discontinuous in Q
    there, so a rounding of the Q decides) is checked as Boltzmann(Q, α) of the kernel's own Q."""
    steady_B = np.ones(len(got.q_BA), dtype=bool)
    if alpha is not None:
        alpha_B = np.broadcast_to(np.asarray(alpha, dtype=np.float64), steady_B.shape)
        gap_B = np.abs(got.q_BA - want.q_BA).max(axis=1, initial=0.0)
        steady_B = gap_B <= TOL * alpha_B
        with np.errstate(all="ignore"):
            own = boltzmann(got.q_BA[~steady_B], alpha_B[~steady_B])
        np.testing.assert_allclose(got.probs_BA[~steady_B], own, rtol=TOL, atol=TOL)
    for field in fields:
        g, w = getattr(got, field), getattr(want, field)
        if field == "probs_BA":
            g, w = g[steady_B], w[steady_B]
        np.testing.assert_allclose(g, w, rtol=TOL, atol=TOL, err_msg=field)
    if q:  # relative to the blended Q, or to the inputs' scale where the blend cancels them
        scale = np.abs(got.q_BA).max(initial=0.0) if scale is None else scale
        np.testing.assert_allclose(got.q_BA, want.q_BA, rtol=TOL, atol=TOL * scale, err_msg="q_BA")


def _rows(result, keep: np.ndarray) -> SimpleNamespace:
    return SimpleNamespace(**{f: getattr(result, f)[keep] for f in (*FIELDS, "q_BA")})


@st.composite
def cases(draw, shapes=("random", "copies", "flat"), max_rows: int = 8):
    """Q-vectors with the structure the maths must survive: copies of the task vector (Σw =
    0), flat vectors, huge and tiny magnitudes (or, `shapes`, the ill-conditioned ones); masks;
    a scalar or per-row temperature."""
    n_rows = draw(st.integers(1, max_rows))
    n_slots = draw(st.integers(0, 8))
    n_act = draw(st.integers(1, 12))
    exponent = draw(st.sampled_from([-300, -12, 0, 0, 3, 300]))
    elems = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
    q_task = draw(arrays(np.float64, (n_rows, n_act), elements=elems)) * 10.0**exponent
    q_impact = draw(arrays(np.float64, (n_rows, n_slots, n_act), elements=elems)) * 10.0**exponent
    shape = draw(st.sampled_from(shapes))
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


def _random_rows(rng: np.random.Generator, n_rows: int, n_slots: int, n_actions: int):
    """Rows as a policy server sees them: Q-values of a few scales, some partner slots
    masked, copies of the task vector (Σw = 0) and flat vectors now and then, a temperature
    per row."""
    scale = rng.choice([0.01, 1.0, 30.0], size=(n_rows, 1))
    q_task = rng.standard_normal((n_rows, n_actions)) * scale
    q_impact = rng.standard_normal((n_rows, n_slots, n_actions)) * scale[:, :, None]
    copies = rng.random((n_rows, n_slots)) < 0.05
    q_impact[copies] = np.repeat(q_task[:, None, :], n_slots, axis=1)[copies]
    flat = rng.random(n_rows) < 0.05
    q_task[flat] = q_task[flat, :1]
    mask = rng.random((n_rows, n_slots)) < 0.8
    alpha = rng.choice([0.02, 0.1, 1.0], size=n_rows) * rng.uniform(0.5, 2.0, n_rows)
    epsilon = rng.choice([0.0, 0.04, 1.0], size=n_rows)
    return q_task, q_impact, mask, alpha, epsilon


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("normalise", [True, False])
def test_ten_thousand_random_rows_equal_the_reference(method: str, normalise: bool) -> None:
    """10,000 rows of 5 actions (the particle world's) and up to 4 partners, in batches of 1 to
    64 rows: every field of the compiled blend within 1e-9 of numpy's."""
    rng = np.random.default_rng(len(method) * 2 + normalise)
    done, worst = 0, {field: 0.0 for field in (*FIELDS, "q_BA")}
    while done < 10_000:
        n_rows = int(rng.choice([1, 1, 2, 7, 64]))
        q_task, q_impact, mask, alpha, epsilon = _random_rows(
            rng, n_rows, int(rng.integers(0, 5)), 5
        )
        bound = {"regret_bound": epsilon} if method == "aail_bounded" else {}
        got = blend(method, q_task, q_impact, alpha, mask, normalise=normalise, **bound)
        with np.errstate(all="ignore"):  # the reference's masked divisions
            want = blend_vectorised(
                method, q_task, q_impact, alpha, mask, normalise=normalise, **bound
            )
        for field in worst:
            gap = np.abs(getattr(got, field) - getattr(want, field))
            if field == "q_BA":  # relative to the row's scale
                gap = gap / np.maximum(np.abs(want.q_BA).max(axis=1, keepdims=True), 1.0)
            worst[field] = max(worst[field], float(gap.max(initial=0.0)))
        done += n_rows
    assert max(worst.values()) <= TOL, worst


@settings(max_examples=300, deadline=None)
@given(
    case=cases(),
    method=st.sampled_from(["sl", "nail", "aail"]),
    normalise=st.booleans(),
)
def test_compiled_equals_the_reference(case, method: str, normalise: bool) -> None:
    q_task, q_impact, mask, alpha = case
    with np.errstate(all="ignore"):
        want = blend_vectorised(method, q_task, q_impact, alpha, mask, normalise=normalise)
    got = blend(method, q_task, q_impact, alpha, mask, normalise=normalise)
    scale = max(np.abs(q_task).max(initial=0.0), np.abs(q_impact).max(initial=0.0))
    # rows whose impact policies are all within rounding of the task policy (a huge α flattens
    # them): their JS distances, hence ŵ and the blend, are rounding in both implementations
    alpha_B1 = np.broadcast_to(np.asarray(alpha, dtype=np.float64), q_task.shape[:1])[:, None]
    with np.errstate(all="ignore"):
        pi_task = boltzmann(q_task, alpha_B1[:, 0])
        pi_impact = boltzmann(q_impact, alpha_B1) if q_impact.size else q_impact
        jsd = js_distance(pi_task[:, None, :], pi_impact) if q_impact.size else q_impact[..., 0]
    # (an exact copy of the task's Q-vector is not rounding: both must give it distance 0; a
    # policy that only rounds to the task's, e.g. under a huge α, may come out 0 in one and
    # 1e-17 in the other, which turns an equal share of ŵ into all-or-nothing)
    exact_copy_BP = (q_impact == q_task[:, None, :]).all(axis=2)
    rounding_B = (
        ((jsd < 1e-4) & mask & ~exact_copy_BP).any(axis=1)
        if method == "aail"
        else mask[:, 0:0].any(axis=1)
    )
    keep = ~rounding_B
    _assert_close(_rows(got, keep), _rows(want, keep), alpha_B1[keep, 0], scale=scale)
    np.testing.assert_allclose(got.probs_BA.sum(axis=1), 1.0, rtol=0, atol=1e-12)


@settings(max_examples=300, deadline=None)
@given(
    case=cases(shapes=("random", "copies", "flat")),
    epsilon=st.sampled_from([0.0, 1e-12, 0.02, 0.5, 5.0, 1e300, "per row"]),
)
def test_the_bound_equals_the_reference(case, epsilon) -> None:
    """aail_bounded: aail's fields, with its policy π_C bounded by eq. R1 as
    `regret_bound.bound_rows` bounds it (ε = 0: the task policy on the rows without ties; a
    huge ε: π_C). π_C itself is held to the reference by the tests above."""
    q_task, q_impact, mask, alpha = case
    if epsilon == "per row":
        epsilon = np.random.default_rng(len(q_task)).choice([0.0, 0.02, 1.0], len(q_task))
    got = blend("aail_bounded", q_task, q_impact, alpha, mask, regret_bound=epsilon)
    aail = blend("aail", q_task, q_impact, alpha, mask)
    for field in ("q_BA", "task_entropy_B", "task_weight_B", "partner_weights_BP"):
        np.testing.assert_array_equal(getattr(got, field), getattr(aail, field))
    alpha_B = np.broadcast_to(np.asarray(alpha, dtype=np.float64), q_task.shape[:1])
    epsilon_B = np.broadcast_to(np.asarray(epsilon, dtype=np.float64), q_task.shape[:1])
    with np.errstate(all="ignore"):
        want = bound_rows(aail.probs_BA, q_task, boltzmann(q_task, alpha_B), epsilon_B)
    np.testing.assert_allclose(got.probs_BA, want, rtol=TOL, atol=TOL)
    np.testing.assert_allclose(got.probs_BA.sum(axis=1), 1.0, rtol=0, atol=1e-12)


def test_the_bound_where_the_blend_puts_nothing_on_the_best_actions() -> None:
    """π_C(S_ε) = 0 (underflow): π_B is the task policy, in both implementations."""
    q_task, q_impact = np.array([[0.0, 1e-3]]), np.array([[[1e6, 0.0]]])  # an unsure task
    got = blend("aail_bounded", q_task, q_impact, 1.0, regret_bound=0.0)
    want = blend_vectorised("aail_bounded", q_task, q_impact, 1.0, regret_bound=0.0)
    assert blend("aail", q_task, q_impact, 1.0).probs_BA[0, 1] == 0.0  # nothing on S_0 = {1}
    np.testing.assert_allclose(got.probs_BA, boltzmann(q_task, 1.0), rtol=0, atol=1e-15)
    np.testing.assert_allclose(got.probs_BA, want.probs_BA, rtol=0, atol=1e-15)


@settings(max_examples=200, deadline=None)
@given(case=cases(shapes=("near copies", "near flat")), method=st.sampled_from(["nail", "aail"]))
def test_ill_conditioned_rows_stay_valid(case, method: str) -> None:
    q_task, q_impact, mask, alpha = case
    got = blend(method, q_task, q_impact, alpha, mask)
    want = blend_vectorised(method, q_task, q_impact, alpha, mask)
    _assert_close(got, want, fields=("task_entropy_B", "task_weight_B"), q=False)
    assert np.isfinite(got.q_BA).all() and (got.probs_BA >= 0).all()
    np.testing.assert_allclose(got.probs_BA.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    active = mask.any(axis=1)
    np.testing.assert_allclose(got.partner_weights_BP.sum(axis=1)[active], 1.0, atol=1e-12)
    assert (got.partner_weights_BP[~mask] == 0).all()


@pytest.mark.parametrize("n_actions", [129, 300])
def test_many_actions(n_actions: int) -> None:
    rng = np.random.default_rng(n_actions)
    for slots in (0, 1, 3):
        q_task, q_impact = (
            rng.normal(size=(2, n_actions)) * 3,
            rng.normal(size=(2, slots, n_actions)),
        )
        for method in ("sl", "nail", "aail"):
            want = blend_vectorised(method, q_task, q_impact, 0.5)
            _assert_close(blend(method, q_task, q_impact, 0.5), want)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_non_finite_q_value_raises(bad: float) -> None:
    """`blend_checked` finds a NaN or infinite Q-value of an unmasked slot in its pass over the
    inputs (the engine answers it as an overflow of the observations); a masked slot is never
    read."""
    task, impact = np.zeros((2, 3)), np.zeros((2, 2, 3))
    mask, alpha = np.ones((2, 2), bool), np.full(2, 0.5)
    for q_task, q_impact in ((task.copy(), impact), (task, impact.copy())):
        (q_task if q_task is not task else q_impact)[1, 1] = bad
        with pytest.raises(FloatingPointError, match="NaN or infinite"):
            blend_module.blend_checked("aail", q_task, q_impact, mask, alpha, True, None)
    masked = impact.copy()
    masked[1, 1] = bad
    mask[1, 1] = False
    blend_module.blend_checked("aail", task, masked, mask, alpha, True, None)


def test_masked_slots_are_never_read() -> None:
    q_task = [[0.0, 1.0, 3.0]]
    q_impact = [[[np.nan, 0.0, np.inf], [2.0, 0.0, 1.0]]]
    got = blend("aail", q_task, q_impact, 0.5, [[False, True]])
    assert got.partner_weights_BP.tolist() == [[0.0, 1.0]]
    reference = blend_vectorised("aail", q_task, np.nan_to_num(q_impact), 0.5, [[False, True]])
    _assert_close(got, reference)


def test_edge_cases_by_hand() -> None:
    q = [[0.0, 1.0, 2.0]]
    # Σw = 0: every impact policy equals the task policy -> equal shares, the task's policy
    same = blend("aail", q, [[q[0], q[0]]], 1.0)
    assert same.partner_weights_BP.tolist() == [[0.5, 0.5]]
    np.testing.assert_allclose(same.probs_BA, blend("sl", q, np.zeros((1, 0, 3)), 1.0).probs_BA)
    # no partner: w_t = 1 and Q_C = Q_t - mean, the SL policy
    alone = blend("aail", q, np.zeros((1, 0, 3)), 1.0)
    assert alone.task_weight_B[0] == 1.0
    np.testing.assert_allclose(alone.q_BA[0], [-1.0, 0.0, 1.0], rtol=1e-12, atol=1e-15)
    # one action: certain policy, zero entropy, w_t = 1 by definition
    one = blend("aail", [[5.0]], [[[2.0]]], 1e-9)
    assert (one.probs_BA[0].tolist(), one.task_entropy_B[0], one.task_weight_B[0]) == (
        [1.0],
        0.0,
        1.0,
    )
    # a flat impact vector has z = 0 and scale 0: Q_C = (w_t s_t)(w_t z_t) = w_t² (Q_t - mean)
    flat = blend("aail", q, [[[7.0, 7.0, 7.0]]], 1.0)
    w_t = flat.task_weight_B[0]
    assert flat.partner_weights_BP.tolist() == [[1.0]] and 0 < w_t < 1
    np.testing.assert_allclose(flat.q_BA[0], [w_t**2 * x for x in [-1.0, 0.0, 1.0]], rtol=1e-12)
    # huge Q and a tiny temperature give a one-hot policy without overflow or NaN
    huge = blend("aail", [[1e300, -1e300, 0.0]], [[[-1e300, 1e300, 0.0]]], 1e-300)
    assert np.isfinite(huge.q_BA).all() and sorted(huge.probs_BA[0]) == [0.0, 0.0, 1.0]
    empty = blend("aail", np.zeros((0, 3)), np.zeros((0, 2, 3)), 1.0)
    assert empty.probs_BA.shape == (0, 3) and empty.partner_weights_BP.shape == (0, 2)


def test_js_distance_with_an_underflowed_mixture() -> None:
    """p = 5e-324 against q = 0: m = (p + q) / 2 rounds to 0; numpy then divides by 0 (a
    distance of 1), and so must the kernel, without raising."""
    q_task = np.array([[0.0, -745.0 - 0.13]])  # exp gives the smallest subnormal for action 1
    q_impact = np.array([[[0.0, -1e6]]])
    with np.errstate(divide="ignore"):
        reference = blend_vectorised("aail", q_task, q_impact, 1.0)
    _assert_close(blend("aail", q_task, q_impact, 1.0), reference)


def test_the_working_form_is_required() -> None:
    """`blend_checked` takes C-contiguous float64 and bool arrays as they are (`blend` makes
    them so): anything else is a TypeError, never a wrong read."""
    q_task, q_impact = np.zeros((2, 3)), np.zeros((2, 1, 3))
    alpha, mask = np.ones(2), np.ones((2, 1), bool)
    with pytest.raises(TypeError):
        blend_module.blend_checked("aail", q_task.T.copy().T, q_impact, mask, alpha, True, None)
    with pytest.raises(TypeError):
        blend_module.blend_checked("aail", q_task, q_impact, mask.astype(int), alpha, True, None)
    # `blend` itself takes any layout, a broadcast α; both take read-only arrays
    frozen = np.zeros((2, 3))
    frozen.flags.writeable = False
    got = blend("aail", frozen, np.zeros((2, 1, 3)), 0.5, regret_bound=None)
    assert got.probs_BA.shape == (2, 3)


@settings(max_examples=100, deadline=None)
@given(case=cases(max_rows=19), method=st.sampled_from(["sl", "nail", "aail"]))
def test_a_batch_equals_its_rows_one_at_a_time(case, method: str) -> None:
    """Each row of a batch is blended alone: bit for bit what the row gives on its own."""
    q_task, q_impact, mask, alpha = case
    alpha_B = np.broadcast_to(np.asarray(alpha, dtype=np.float64), q_task.shape[:1])
    whole = blend(method, q_task, q_impact, alpha_B, mask)
    rows = [
        blend(method, q_task[b : b + 1], q_impact[b : b + 1], alpha_B[b : b + 1], mask[b : b + 1])
        for b in range(len(q_task))
    ]
    for b, row in enumerate(rows):
        for field in (*FIELDS, "q_BA"):
            assert np.array_equal(getattr(row, field)[0], getattr(whole, field)[b], equal_nan=True)
