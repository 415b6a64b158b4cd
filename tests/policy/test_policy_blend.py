"""policy.blend: SL / NAIL / AAIL by hand, against a naive per-row loop, and its properties."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from policy.blend import blend, mix_goal_beliefs

LN3 = math.log(3.0)


# --- a naive reference, one row at a time, in plain Python ----------------------------------


def _softmax(q: list[float], alpha: float) -> list[float]:
    top = max(q)
    e = [math.exp((x - top) / alpha) for x in q]
    return [x / sum(e) for x in e]


def _entropy_norm(p: list[float]) -> float:
    if len(p) == 1:
        return 0.0
    return -sum(x * math.log(x) for x in p if x > 0) / math.log(len(p))


def _jsd(p: list[float], q: list[float]) -> float:
    def kl(a: list[float], m: list[float]) -> float:
        return sum(x * math.log2(x / y) for x, y in zip(a, m, strict=True) if x > 0)

    m = [(x + y) / 2 for x, y in zip(p, q, strict=True)]
    return math.sqrt(min(max(0.5 * kl(p, m) + 0.5 * kl(q, m), 0.0), 1.0))


def _z_and_scale(q: list[float]) -> tuple[list[float], float]:
    mean = sum(q) / len(q)
    std = math.sqrt(sum((x - mean) ** 2 for x in q) / len(q))
    if std <= 1e-12 * max(abs(x) for x in q):
        return [0.0] * len(q), 0.0
    return [(x - mean) / std for x in q], std


def _naive_row(
    method: str, q_t: list[float], q_is: list[list[float]], alpha: float
) -> tuple[list[float], float, list[float]]:
    """(blended q, task weight, weight per active partner) for one row."""
    n_act = len(q_t)
    if method == "sl":
        return q_t, 1.0, [0.0] * len(q_is)
    if method == "nail":
        k = 1 + len(q_is)
        q = [(q_t[a] + sum(qi[a] for qi in q_is)) / k for a in range(n_act)]
        return q, 1 / k, [1 / len(q_is)] * len(q_is) if q_is else []
    if not q_is:
        mean = sum(q_t) / n_act
        return [x - mean for x in q_t], 1.0, []
    pi_t = _softmax(q_t, alpha)
    w_t = 1.0 if n_act == 1 else 1 - n_act ** _entropy_norm(pi_t) / n_act
    w = [_jsd(pi_t, _softmax(qi, alpha)) for qi in q_is]
    w_hat = [x / sum(w) for x in w] if sum(w) > 0 else [1 / len(w)] * len(w)
    z_t, s_t = _z_and_scale(q_t)
    zs = [_z_and_scale(qi) for qi in q_is]
    s_c = w_t * s_t + (1 - w_t) * sum(wh * s for wh, (_, s) in zip(w_hat, zs, strict=True))
    z_c = [
        w_t * z_t[a] + (1 - w_t) * sum(wh * z[a] for wh, (z, _) in zip(w_hat, zs, strict=True))
        for a in range(n_act)
    ]
    return [s_c * x for x in z_c], w_t, w_hat


@pytest.mark.parametrize("method", ["sl", "nail", "aail"])
@pytest.mark.parametrize("n_slots", [0, 1, 2, 3, 4, 5])
def test_batched_blend_matches_naive_loop(method: str, n_slots: int) -> None:
    rng = np.random.default_rng(100 * n_slots + len(method))
    n_rows, n_act = 7, 5
    q_task = rng.normal(size=(n_rows, n_act)) * rng.choice([0.01, 1.0, 30.0], size=(n_rows, 1))
    q_impact = rng.normal(size=(n_rows, n_slots, n_act)) * 3
    q_impact[0] = q_task[0, None, :]  # identical policies: every w_i = 0
    mask = rng.random((n_rows, n_slots)) < 0.7
    q_impact[~mask] = np.nan  # masked slots must be ignored entirely
    alpha = rng.uniform(0.1, 3.0, size=n_rows)

    result = blend(method, q_task, q_impact, alpha, mask)  # type: ignore[arg-type]

    for b in range(n_rows):
        active = [q_impact[b, p].tolist() for p in range(n_slots) if mask[b, p]]
        q, w_t, w_hat = _naive_row(method, q_task[b].tolist(), active, float(alpha[b]))
        np.testing.assert_allclose(result.q_BA[b], q, atol=1e-10)
        np.testing.assert_allclose(result.probs_BA[b], _softmax(q, float(alpha[b])), atol=1e-10)
        assert result.task_weight_B[b] == pytest.approx(w_t, abs=1e-12)
        np.testing.assert_allclose(result.partner_weights_BP[b][mask[b]], w_hat, atol=1e-12)
        assert (result.partner_weights_BP[b][~mask[b]] == 0).all()
        pi_t = _softmax(q_task[b].tolist(), float(alpha[b]))
        assert result.task_entropy_B[b] == pytest.approx(_entropy_norm(pi_t), abs=1e-12)


# --- hand-computed blends -------------------------------------------------------------------


def test_aail_by_hand_two_actions_one_partner() -> None:
    # α = 1, Q_t = [ln 3, 0] -> π_t = [3/4, 1/4]; Q_i = [0, ln 3] -> π_i = [1/4, 3/4]
    h = -(0.75 * math.log2(0.75) + 0.25 * math.log2(0.25))  # bits; log2 |A| = 1
    w_t = 1 - 2**h / 2  # eq. 9 ≈ 0.12262
    # z_t = [1, -1], z_i = [-1, 1], s_t = s_i = ln3 / 2 -> Q_C = (2 w_t - 1) (ln3 / 2) [1, -1]
    expected_q = (2 * w_t - 1) * LN3 / 2 * np.array([1.0, -1.0])
    result = blend("aail", [[LN3, 0.0]], [[[0.0, LN3]]], 1.0)
    assert result.task_entropy_B[0] == pytest.approx(h)
    assert result.task_weight_B[0] == pytest.approx(0.1226173, abs=1e-7)
    np.testing.assert_allclose(result.partner_weights_BP, [[1.0]])
    np.testing.assert_allclose(result.q_BA[0], expected_q)
    np.testing.assert_allclose(result.q_BA[0], [-0.4145972, 0.4145972], atol=1e-7)


def test_aail_by_hand_partner_weights_follow_jsd() -> None:
    # tiny α: π_t = one-hot on action 0. Partner 1 agrees (JSD 0), partner 2 is a disjoint one-hot
    # (JSD 1), so ŵ = [0, 1]. w_t = 1 - 1/3 = 2/3.
    q_t = [[3.0, 0.0, 0.0]]
    q_i = [[[6.0, 0.0, 0.0], [0.0, 0.0, 3.0]]]
    result = blend("aail", q_t, q_i, 1e-6)
    np.testing.assert_allclose(result.partner_weights_BP, [[0.0, 1.0]], atol=1e-12)
    assert result.task_weight_B[0] == pytest.approx(2 / 3)
    # z_t = [√2, -1/√2, -1/√2], z_2 = [-1/√2, -1/√2, √2], s_t = s_2 = √2
    r2 = math.sqrt(2.0)
    z_c = 2 / 3 * np.array([r2, -1 / r2, -1 / r2]) + 1 / 3 * np.array([-1 / r2, -1 / r2, r2])
    np.testing.assert_allclose(result.q_BA[0], r2 * z_c, atol=1e-12)
    np.testing.assert_allclose(result.q_BA[0], [1.0, -1.0, 0.0], atol=1e-12)


def test_nail_by_hand_is_raw_average() -> None:
    result = blend("nail", [[1.0, 2.0]], [[[3.0, 0.0], [5.0, 10.0]]], 1.0)
    np.testing.assert_allclose(result.q_BA, [[3.0, 4.0]])
    np.testing.assert_allclose(result.task_weight_B, [1 / 3])
    np.testing.assert_allclose(result.partner_weights_BP, [[0.5, 0.5]])


def test_sl_ignores_partners() -> None:
    result = blend("sl", [[1.0, 2.0]], [[[30.0, 0.0]]], 0.5)
    np.testing.assert_array_equal(result.q_BA, [[1.0, 2.0]])
    np.testing.assert_allclose(result.probs_BA[0], [1 / (1 + math.e**2), 1 / (1 + math.e**-2)])
    np.testing.assert_array_equal(result.task_weight_B, [1.0])
    np.testing.assert_array_equal(result.partner_weights_BP, [[0.0]])


# --- consequences of the normalisation ------------------------------------------------------


def test_aail_without_partners_is_sl_up_to_a_shift() -> None:
    q_task = np.array([[1.0, -2.0, 0.5], [100.0, 101.0, 99.0]])
    for q_impact, mask in [
        (np.zeros((2, 0, 3)), None),
        (np.ones((2, 2, 3)), np.zeros((2, 2), bool)),
    ]:
        aail = blend("aail", q_task, q_impact, 0.7, mask)
        sl = blend("sl", q_task, q_impact, 0.7, mask)
        np.testing.assert_allclose(aail.q_BA, q_task - q_task.mean(axis=1, keepdims=True))
        np.testing.assert_allclose(aail.probs_BA, sl.probs_BA, atol=1e-12)
        np.testing.assert_array_equal(aail.task_weight_B, [1.0, 1.0])


def test_aail_with_zero_task_weight_follows_the_single_partner() -> None:
    # A uniform task policy (all Q equal) has H = 1 and so w_t = 0 (eq. 9)
    q_impact = np.array([[[0.3, 2.0, -1.0, 0.0]]])
    result = blend("aail", [[4.0, 4.0, 4.0, 4.0]], q_impact, 0.8)
    assert result.task_weight_B[0] == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(result.probs_BA, blend("sl", q_impact[:, 0], q_impact, 0.8).probs_BA)


def test_aail_weights_by_preference_not_by_reward_scale() -> None:
    # Uniform task policy (w_t = 0) and, at small α, two one-hot impact policies on different
    # actions: both at the same JSD from π_t, so ŵ = [1/2, 1/2]. Partner 2's rewards are 1000x
    # larger; raw averaging (NAIL) follows it, while the standardised preferences cancel exactly.
    q_task = [[0.0, 0.0, 0.0]]
    q_impact = [[[1.0, 0.0, 0.5], [0.0, 1000.0, 500.0]]]
    result = blend("aail", q_task, q_impact, 1e-2)
    np.testing.assert_allclose(result.partner_weights_BP, [[0.5, 0.5]], atol=1e-12)
    np.testing.assert_allclose(result.q_BA, [[0.0, 0.0, 0.0]], atol=1e-9)
    np.testing.assert_allclose(result.probs_BA, [[1 / 3] * 3])
    assert blend("nail", q_task, q_impact, 1e-2).probs_BA[0, 1] == pytest.approx(1.0)


def test_aail_blended_preference_ignores_the_scale_of_one_network() -> None:
    # Scaling an impact Q-vector by c > 0 where its policy stays one-hot (so its weight does not
    # change) only rescales the blended Q: the blended preference z_C is the same.
    q_task = np.array([[2.0, 0.0, 1.0, 0.5]])
    q_impact = np.array([[[0.0, 1.0, 0.2, 0.0]]])
    z = [blend("aail", q_task, q_impact * c, 1e-3).q_BA for c in (1.0, 50.0)]
    standardised = [(q - q.mean()) / q.std() for q in z]
    np.testing.assert_allclose(standardised[0], standardised[1], atol=1e-12)


def test_all_impact_policies_equal_to_task_gives_equal_partner_weights() -> None:
    q = np.array([[0.0, 1.0, 2.0]])
    result = blend("aail", q, np.stack([q, q, q], axis=1), 1.0)
    np.testing.assert_allclose(result.partner_weights_BP, [[1 / 3] * 3])
    np.testing.assert_allclose(result.probs_BA, blend("sl", q, np.zeros((1, 0, 3)), 1.0).probs_BA)


def test_one_action_and_empty_batch() -> None:
    for method in ("sl", "nail", "aail"):
        result = blend(method, [[5.0], [-1.0]], [[[2.0]], [[7.0]]], 1e-9)
        np.testing.assert_array_equal(result.probs_BA, [[1.0], [1.0]])
        assert np.isfinite(result.q_BA).all()
        empty = blend(method, np.zeros((0, 3)), np.zeros((0, 2, 3)), 1.0)
        assert empty.probs_BA.shape == (0, 3) and empty.partner_weights_BP.shape == (0, 2)


@pytest.mark.parametrize("method", ["sl", "nail", "aail"])
@pytest.mark.parametrize("alpha", [1e-9, 1.0, 1e6])
def test_extreme_q_and_alpha_give_no_nan(method: str, alpha: float) -> None:
    q_task = np.array([[1e300, -1e300, 0.0], [1e-300, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    q_impact = np.stack([q_task[::-1], -q_task, q_task], axis=1)
    result = blend(method, q_task, q_impact, alpha)  # type: ignore[arg-type]
    for field in (result.q_BA, result.probs_BA, result.task_weight_B, result.partner_weights_BP):
        assert np.isfinite(field).all()
    np.testing.assert_allclose(result.probs_BA.sum(axis=1), 1.0)


# --- bad input ------------------------------------------------------------------------------


def test_bad_inputs_are_named() -> None:
    q_t, q_i = np.zeros((2, 3)), np.zeros((2, 1, 3))
    with pytest.raises(
        ValueError, match=r"method: .*'softmax'.*\('sl', 'nail', 'aail', 'aail_bounded'\)"
    ):
        blend("softmax", q_t, q_i, 1.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"q_task_BA: expected shape \(B, A\), got \(3,\)"):
        blend("aail", np.zeros(3), q_i, 1.0)
    with pytest.raises(ValueError, match=r"q_impact_BPA: .*\(2, P, 3\).*got \(2, 1, 4\)"):
        blend("aail", q_t, np.zeros((2, 1, 4)), 1.0)
    with pytest.raises(ValueError, match=r"q_impact_BPA: .*got \(3, 1, 3\)"):
        blend("nail", q_t, np.zeros((3, 1, 3)), 1.0)
    with pytest.raises(ValueError, match=r"partner_mask_BP: .*\(2, 1\)"):
        blend("aail", q_t, q_i, 1.0, np.ones((2, 1)))
    with pytest.raises(ValueError, match=r"q_impact_BPA .*non-finite"):
        blend("aail", q_t, np.full((2, 1, 3), np.inf), 1.0)
    with pytest.raises(ValueError, match=r"q_task_BA: .*at least one action"):
        blend("aail", np.zeros((2, 0)), np.zeros((2, 1, 0)), 1.0)
    with pytest.raises(ValueError, match="alpha"):
        blend("aail", q_t, q_i, 0.0)


# --- goal beliefs ---------------------------------------------------------------------------


def test_mix_goal_beliefs_by_hand() -> None:
    q_BPGA = np.array([[[[1.0, 0.0], [0.0, 4.0]], [[2.0, 2.0], [9.0, 9.0]]]])  # (1, 2, 2, 2)
    probs_BPG = np.array([[[0.25, 0.75], [1.0, 0.0]]])
    np.testing.assert_allclose(mix_goal_beliefs(q_BPGA, probs_BPG), [[[0.25, 3.0], [2.0, 2.0]]])


def test_mix_goal_beliefs_rejects_bad_beliefs() -> None:
    q = np.zeros((1, 2, 3, 4))
    with pytest.raises(ValueError, match=r"goal_probs_BPG: .*sum to 1"):
        mix_goal_beliefs(q, np.full((1, 2, 3), 0.3))
    with pytest.raises(ValueError, match=r"goal_probs_BPG: .*non-negative"):
        mix_goal_beliefs(q, np.array([[[1.5, -0.5, 0.0]] * 2]))
    with pytest.raises(
        ValueError, match=r"goal_probs_BPG: expected shape \(B, P, G\) = \(1, 2, 3\)"
    ):
        mix_goal_beliefs(q, np.full((1, 2, 2), 0.5))
    with pytest.raises(ValueError, match=r"q_BPGA: expected shape \(B, P, G, A\)"):
        mix_goal_beliefs(np.zeros((2, 3, 4)), np.full((2, 3), 0.5))
    # a masked partner may carry anything
    probs = np.array([[[1.0, 0.0, 0.0], [np.nan, 0.0, 0.0]]])
    mixed = mix_goal_beliefs(q, probs, partner_mask_BP=np.array([[True, False]]))
    np.testing.assert_array_equal(mixed, np.zeros((1, 2, 4)))


# --- properties -----------------------------------------------------------------------------


@st.composite
def blend_cases(
    draw: st.DrawFn, integer_q: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    n_rows, n_slots = draw(st.integers(1, 3)), draw(st.integers(0, 3))
    n_act = draw(st.integers(1, 4))
    q_elems = (
        st.integers(-1000, 1000).map(float) if integer_q else st.floats(-1e6, 1e6, allow_nan=False)
    )
    q_task = draw(arrays(np.float64, (n_rows, n_act), elements=q_elems))
    q_impact = draw(arrays(np.float64, (n_rows, n_slots, n_act), elements=q_elems))
    mask = draw(arrays(np.bool_, (n_rows, n_slots)))
    return q_task, q_impact, mask, draw(st.floats(1e-6, 1e3))


@settings(max_examples=120, deadline=None)
@given(case=blend_cases(), method=st.sampled_from(["sl", "nail", "aail"]))
def test_blend_outputs_are_finite_distributions_and_weights_in_range(
    case: tuple[np.ndarray, np.ndarray, np.ndarray, float], method: str
) -> None:
    q_task, q_impact, mask, alpha = case
    result = blend(method, q_task, q_impact, alpha, mask)  # type: ignore[arg-type]
    assert np.isfinite(result.q_BA).all() and np.isfinite(result.probs_BA).all()
    np.testing.assert_allclose(result.probs_BA.sum(axis=1), 1.0, atol=1e-12)
    for w in (result.task_weight_B, result.partner_weights_BP, result.task_entropy_B):
        assert ((w >= 0) & (w <= 1 + 1e-12)).all()
    sums = result.partner_weights_BP.sum(axis=1)
    np.testing.assert_allclose(sums, np.where(mask.any(axis=1) & (method != "sl"), 1.0, 0.0))


@settings(max_examples=120, deadline=None)
@given(
    case=blend_cases(integer_q=True),
    shift=st.integers(-1000, 1000),
    method=st.sampled_from(["sl", "nail", "aail"]),
)
def test_blend_policy_is_invariant_to_a_constant_added_to_one_q_vector(
    case: tuple[np.ndarray, np.ndarray, np.ndarray, float], shift: int, method: str
) -> None:
    # Integer-valued Q keeps q + shift exact, so the property is tested without rounding noise
    # (standardisation amplifies the rounding of a nearly flat Q-vector).
    q_task, q_impact, mask, alpha = case
    base = blend(method, q_task, q_impact, alpha, mask)  # type: ignore[arg-type]
    moved_task = q_task.copy()
    moved_task[0] += shift
    moved_impact = q_impact.copy()
    moved_impact[-1, :1] += shift  # the first partner slot of the last row
    for qt, qi in ((moved_task, q_impact), (q_task, moved_impact)):
        moved = blend(method, qt, qi, alpha, mask)  # type: ignore[arg-type]
        np.testing.assert_allclose(moved.probs_BA, base.probs_BA, atol=1e-9)
