"""The blend of eqs. 8-10 and the regret bound of eq. R1, compiled by numba: `policy.blend`'s
kernel, and the inverse-CDF sampling of `policy.sampling`.

Why compiled: the blend of one row is a few hundred double operations over vectors of a
handful of actions; numpy spends ~40 calls on them, and its per-call overhead, not the
arithmetic, then sets a single act's latency. Here each row is plain loops over doubles.

The semantics are those of `policy.blend`'s vectorised numpy path, the reference, documented
there (standardisation and scale rule, the Σw = 0 fallback, rows without partners, one
action); each helper below names the numpy function it follows. Sums run in plain order, so
the results differ from numpy's (pairwise sums) by rounding: tests/policy/test_blend_kernel.py
holds them to the reference within 1e-9. Every row is computed alone, so a row of a batch
equals the same row blended on its own, bit for bit.

Inputs are trusted (`policy.blend` checks them: alpha > 0, A >= 1, C-contiguous float64),
except for finiteness: a NaN or infinite Q-value of an unmasked slot raises
FloatingPointError. Masked partner slots are never read.

The signatures are explicit, so the kernels compile (or load from numba's on-disk cache) when
this module is imported, never on a request.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

from policy.kernel_maths import LOG2_E, exp, log

SL, NAIL, AAIL = 0, 1, 2  # `blend_rows`' method codes (aail_bounded is AAIL with `bounded`)
FLAT_STD_RTOL = 1e-12  # policy.blend.FLAT_STD_RTOL

# Every function: cache=True (compiled once on a machine, then loaded from numba's cache),
# nogil, and error_model="numpy": a float division by zero gives inf or NaN as in numpy (the JS
# terms of an underflowed mixture rely on it) instead of raising ZeroDivisionError. The helpers
# are inlined into `blend_rows` (inline="always"): a call that passes arrays takes and releases a
# reference to each, atomic operations that cost a tenth of a 256-row batch's blend otherwise.

f8, i8, b1 = types.float64, types.int64, types.boolean


def in_array(dtype: types.Type, ndim: int) -> types.Array:
    """A C-contiguous input array type that also takes read-only arrays (the engine's
    constants, broadcast values)."""
    return types.Array(dtype, ndim, "C", readonly=True)


def out_array(dtype: types.Type, ndim: int) -> types.Array:
    return types.Array(dtype, ndim, "C")


_BLEND_SIGNATURE = types.void(
    *(
        i8,
        in_array(f8, 2),
        in_array(f8, 3),
        in_array(f8, 1),
        in_array(b1, 2),
        b1,
        in_array(f8, 1),
        b1,
    ),
    *(out_array(f8, 2), out_array(f8, 2), out_array(f8, 1), out_array(f8, 1), out_array(f8, 2)),
)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _largest(v):
    """The largest entry of a non-empty vector (a loop: the array method would take a
    reference to v, an atomic operation, on every row)."""
    top = v[0]
    for a in range(1, v.size):
        top = max(top, v[a])
    return top


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _boltzmann(q, alpha, out):
    """`maths.boltzmann` (eq. 2) of one Q-vector into `out`; returns the sum of its
    exponentials (with `_log_policy`, the policy's logarithm without a logarithm per action)."""
    top = _largest(q)
    total = 0.0
    for a in range(q.size):
        out[a] = exp((q[a] - top) / alpha)
        total += out[a]
    for a in range(q.size):
        out[a] = out[a] / total
    return total


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _renormalised(p, out):
    """p divided by its sum (as `policy._validate.prob_array` hands policies to `maths`);
    returns that sum."""
    total = 0.0
    for a in range(p.size):
        total += p[a]
    for a in range(p.size):
        out[a] = p[a] / total
    return total


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _log_policy(q, alpha, log_shift, out):
    """log of `_boltzmann(q, alpha)` renormalised once: (q - max q)/α minus `log_shift` (the log
    of the exponentials' sum plus the log of the renormalising sum). Finite where the policy
    underflowed to 0, and there never read: every sum below skips p = 0."""
    top = _largest(q)
    for a in range(q.size):
        out[a] = (q[a] - top) / alpha - log_shift


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _entropy(p, log_p):
    """`maths.normalized_entropy` of the (renormalised) policy p, in [0, 1]; 0 for one action.
    Σ p log p with log p given (`_log_policy`): the same sum, one log per row, not per action."""
    if p.size == 1:
        return 0.0
    h = 0.0
    for a in range(p.size):
        if p[a] > 0:
            h -= p[a] * log_p[a]
    return min(max(h / math.log(p.size), 0.0), 1.0)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _impact_policies(q_impact, b, mask, alpha, out):
    """The renormalised Boltzmann policy (eq. 2) of each active partner slot s of row b, into
    out[s A : (s + 1) A] (an inactive slot's: uniform, never read). As `_boltzmann` then
    `_renormalised` per slot, but with every exponential in one loop over the block, which
    LLVM vectorises (`policy.kernel_maths`)."""
    n_slots, n_actions = q_impact.shape[1], q_impact.shape[2]
    for s in range(n_slots):
        row = s * n_actions
        if mask[b, s]:
            top = q_impact[b, s, 0]
            for a in range(1, n_actions):
                top = max(top, q_impact[b, s, a])
            for a in range(n_actions):
                out[row + a] = (q_impact[b, s, a] - top) / alpha
        else:
            for a in range(n_actions):
                out[row + a] = 0.0
    for i in range(n_slots * n_actions):
        out[i] = exp(out[i])
    for s in range(n_slots):
        row = s * n_actions
        for _ in range(2):  # divided by the sum, then renormalised as `maths` sees a policy
            total = 0.0
            for a in range(n_actions):
                total += out[row + a]
            for a in range(n_actions):
                out[row + a] = out[row + a] / total


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _js_distances(p, pi_impact, b, mask, log_ratios, distances):
    """`maths.js_distance` (eq. 10) of the task policy p to each active slot's policy in
    `pi_impact` (`_impact_policies`' layout), into `distances` (P,) (0 for inactive slots);
    `log_ratios` (2 P A) is scratch. KL(x ‖ m) in bits is Σ x log2(x / m) over x > 0 (inf where
    m underflowed to 0): the log of the ratio, not a difference of logs, since near a copy
    (x ≈ m) the difference cancels to its rounding and the square root of eq. 10 magnifies
    it. The ratios of every slot are formed first and their logarithms taken in one loop over
    the block (vectorised); a term with x = 0 has ratio 1, so adds 0."""
    n_actions = p.size
    n_slots = distances.size
    for s in range(n_slots):
        for a in range(n_actions):
            x = pi_impact[s * n_actions + a]
            m = 0.5 * (p[a] + x)
            log_ratios[2 * s * n_actions + a] = p[a] / m if p[a] > 0 else 1.0
            log_ratios[(2 * s + 1) * n_actions + a] = x / m if x > 0 else 1.0
    for i in range(2 * n_slots * n_actions):
        log_ratios[i] = log(log_ratios[i])
    for s in range(n_slots):
        distances[s] = 0.0
        if mask[b, s]:
            to_task = 0.0  # KL(p ‖ m), in nats
            to_impact = 0.0  # KL(π_s ‖ m)
            for a in range(n_actions):
                to_task += p[a] * log_ratios[2 * s * n_actions + a]
                to_impact += pi_impact[s * n_actions + a] * log_ratios[(2 * s + 1) * n_actions + a]
            divergence = (0.5 * to_task + 0.5 * to_impact) * LOG2_E
            distances[s] = math.sqrt(min(max(divergence, 0.0), 1.0))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _standardise(q, z):
    """`blend.standardise` of one Q-vector: z-scores into `z`, the scale returned (z = 0 and
    scale 0 when flat)."""
    n = q.size
    magnitude = 0.0
    for a in range(n):
        magnitude = max(magnitude, abs(q[a]))
    divisor = magnitude if magnitude > 0 else 1.0
    mean = 0.0
    for a in range(n):
        z[a] = q[a] / divisor
        mean += z[a]
    mean = mean / n
    squares = 0.0
    for a in range(n):
        z[a] = z[a] - mean
        squares += z[a] * z[a]
    std = math.sqrt(squares / n)
    if std <= FLAT_STD_RTOL:
        for a in range(n):
            z[a] = 0.0
        return 0.0
    for a in range(n):
        z[a] = z[a] / std
    return std * magnitude


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bound(probs, q_task, pi_task, epsilon):
    """Eq. R1 (`regret_bound.bound_rows`) of one row, in place: the actions within ε of the
    task's best share the task policy's mass on them as the blend says, every other action
    keeps its task probability; the task policy itself where the blend puts nothing on them."""
    lowest = _largest(q_task) - epsilon
    task_mass = 0.0
    blend_mass = 0.0
    for a in range(q_task.size):
        if q_task[a] >= lowest:
            task_mass += pi_task[a]
            blend_mass += probs[a]
    for a in range(q_task.size):
        if not blend_mass > 0.0 or q_task[a] < lowest:
            probs[a] = pi_task[a]
        else:
            probs[a] = task_mass * (probs[a] / blend_mass)


@njit(_BLEND_SIGNATURE, cache=True, nogil=True, error_model="numpy")
def blend_rows(
    method,
    q_task,
    q_impact,
    alpha,
    mask,
    normalise,
    epsilon,
    bounded,
    q_out,
    probs_out,
    entropy_out,
    weight_out,
    partners_out,
):
    """B rows blended with `method` (SL, NAIL or AAIL; `policy.blend._vectorised`), the policy
    bounded by eq. R1 with ε = epsilon[b] where `bounded` (AAIL only), into the caller's
    q_out (B, A), probs_out (B, A), entropy_out (B,), weight_out (B,), partners_out (B, P).
    (Output arrays handed in: numba's boxing of a returned tuple of arrays costs more than a
    row's blend.)"""
    n_rows, n_actions = q_task.shape
    n_slots = q_impact.shape[1]
    if not (
        n_actions >= 1
        and q_impact.shape[0] == n_rows
        and q_impact.shape[2] == n_actions
        and alpha.size == n_rows
        and mask.shape == (n_rows, n_slots)
        and (not bounded or epsilon.size == n_rows)
        and q_out.shape == (n_rows, n_actions)
        and probs_out.shape == (n_rows, n_actions)
        and entropy_out.size == n_rows
        and weight_out.size == n_rows
        and partners_out.shape == (n_rows, n_slots)
    ):
        raise ValueError("expected shapes (B, A), (B, P, A), (B,), (B, P)[, (B,)] with A >= 1")
    for b in range(n_rows):
        for a in range(n_actions):
            if not math.isfinite(q_task[b, a]):
                raise FloatingPointError("a Q-value is NaN or infinite")
        for s in range(n_slots):
            if mask[b, s]:
                for a in range(n_actions):
                    if not math.isfinite(q_impact[b, s, a]):
                        raise FloatingPointError("a Q-value is NaN or infinite")
    partners_out[:] = 0.0
    # working memory, one block (an allocation costs more than a row's arithmetic)
    work = np.empty((4 + 4 * n_slots) * n_actions)
    pi_task = work[:n_actions]
    p_task = work[n_actions : 2 * n_actions]  # the task policy as `maths` sees it (renormalised)
    log_p_task = work[2 * n_actions : 3 * n_actions]
    z_task = work[3 * n_actions : 4 * n_actions]
    block = n_slots * n_actions
    pi_impact = work[4 * n_actions : 4 * n_actions + block]  # slot s at [s A, (s + 1) A)
    log_ratios = work[4 * n_actions + block : 4 * n_actions + 3 * block]
    z_impact = work[4 * n_actions + 3 * block :].reshape((n_slots, n_actions))
    for b in range(n_rows):
        q, weights, out = q_task[b], partners_out[b], q_out[b]
        active = 0
        for s in range(n_slots):
            if mask[b, s]:
                active += 1
        sums = _boltzmann(q, alpha[b], pi_task) * _renormalised(pi_task, p_task)
        _log_policy(q, alpha[b], math.log(sums), log_p_task)
        entropy_out[b] = _entropy(p_task, log_p_task)
        if method == SL:
            out[:] = q
            weight_out[b] = 1.0
            probs_out[b] = pi_task
            continue
        if method == NAIL:  # the plain mean of the raw Q-vectors
            out[:] = 0.0
            for s in range(n_slots):
                if mask[b, s]:
                    out += q_impact[b, s]
            for a in range(n_actions):
                out[a] = (q[a] + out[a]) / (1.0 + active)
            for s in range(n_slots):
                weights[s] = (1.0 if mask[b, s] else 0.0) / max(active, 1)
            weight_out[b] = 1.0 / (1.0 + active)
            _boltzmann(out, alpha[b], probs_out[b])
            continue
        # AAIL. Eq. 9 on the task policy's normalised entropy (the reference renormalises the
        # policy once more first, a change in the last bit); the task alone without a partner
        w_t = 1.0
        if active > 0 and n_actions > 1:
            w_t = 1.0 - float(n_actions) ** entropy_out[b] / n_actions
        weight_out[b] = w_t
        # eq. 10: the JS distance of the task policy to each active impact policy, then ŵ
        _impact_policies(q_impact, b, mask, alpha[b], pi_impact)
        _js_distances(p_task, pi_impact, b, mask, log_ratios, weights)
        total = 0.0
        for s in range(n_slots):
            total += weights[s]
        for s in range(n_slots):
            if total > 0:
                weights[s] = weights[s] / total
            else:  # every impact policy equals the task policy: equal shares
                weights[s] = (1.0 if mask[b, s] else 0.0) / max(active, 1)
        # eq. 8, on the raw Q-vectors or on the standardised preferences and their scales
        if not normalise:
            for a in range(n_actions):
                mixed = 0.0  # Σ_i ŵ_i Q_i
                for s in range(n_slots):
                    if mask[b, s]:
                        mixed += weights[s] * q_impact[b, s, a]
                out[a] = w_t * q[a] + (1.0 - w_t) * mixed
        else:
            s_task = _standardise(q, z_task)
            s_mixed = 0.0  # Σ_i ŵ_i s_i
            for s in range(n_slots):
                if mask[b, s]:
                    s_mixed += weights[s] * _standardise(q_impact[b, s], z_impact[s])
            s_blend = w_t * s_task + (1.0 - w_t) * s_mixed
            for a in range(n_actions):
                mixed = 0.0  # Σ_i ŵ_i z_i
                for s in range(n_slots):
                    if mask[b, s]:
                        mixed += weights[s] * z_impact[s, a]
                out[a] = s_blend * (w_t * z_task[a] + (1.0 - w_t) * mixed)
        _boltzmann(out, alpha[b], probs_out[b])
        if bounded:
            _bound(probs_out[b], q, pi_task, epsilon[b])


@njit(
    out_array(i8, 2)(in_array(f8, 2), in_array(f8, 1)), cache=True, nogil=True, error_model="numpy"
)
def sample_rows(probs, u):
    """(2, B) int64: per row the first action whose cumulative probability exceeds u[b] times
    the row's total, at most A - 1 (row 0), and the first most probable action (row 1)
    (`policy.sampling.numpy_sample_rows`: the same sums in the same order, so the same
    actions). One array, not two: numba's boxing of a returned tuple costs more than the
    sampling."""
    n_rows, n_actions = probs.shape
    if n_actions < 1 or u.size != n_rows:
        raise ValueError("expected shapes (B, A) and (B,) with A >= 1")
    out = np.empty((2, n_rows), dtype=np.int64)
    for b in range(n_rows):
        total = 0.0
        for a in range(n_actions):
            total += probs[b, a]
        threshold = u[b] * total
        cdf = 0.0
        below = 0
        best = 0
        for a in range(n_actions):
            cdf += probs[b, a]
            below += cdf <= threshold
            if probs[b, a] > probs[b, best]:
                best = a
        out[0, b] = min(below, n_actions - 1)
        out[1, b] = best
    return out
