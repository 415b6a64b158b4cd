"""The blend of eqs. 8-10 and the regret bound of eq. R1, compiled by numba: `policy.blend`'s
kernel, and the inverse-CDF sampling of `policy.sampling`.

Why compiled: the blend of one row is a few hundred double operations over vectors of a
handful of actions; numpy spends ~40 calls on them, and its per-call overhead, not the
arithmetic, then sets a single act's latency. Here a batch is plain loops over doubles, in
phases over its rows (`blend_rows`).

The semantics are those of `policy.blend`'s vectorised numpy path, the reference, documented
there (standardisation and scale rule, the Σw = 0 fallback, rows without partners, one
action); each helper below names the numpy function it follows. Sums run in plain order, so
the results differ from numpy's (pairwise sums) by rounding: tests/policy/test_blend_kernel.py
holds them to the reference within 1e-9. Every value depends on its own row only, so a row of
a batch equals the same row blended on its own, bit for bit.

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
def _largest(v, start, n):
    """The largest of v[start : start + n], n >= 1."""
    top = v[start]
    for a in range(start + 1, start + n):
        top = max(top, v[a])
    return top


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _centre(q, start, n, alpha, values, divisors):
    """q - max q of the Q-vector q[start : start + n] into the same entries of `values`, and α
    into those of `divisors`: `_divide` then gives (q - max q) / α, the exponent of eq. 2's
    Boltzmann policy (and, less the log of its sum, the policy's logarithm)."""
    top = _largest(q, start, n)
    for a in range(start, start + n):
        values[a] = q[a] - top
        divisors[a] = alpha


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sum_into(values, start, n, divisors):
    """The sum of values[start : start + n] into the same entries of `divisors` (for a
    `_divide` that normalises each group of n); returns it."""
    total = 0.0
    for a in range(start, start + n):
        total += values[a]
    for a in range(start, start + n):
        divisors[a] = total
    return total


# The loops over whole flat blocks below are what LLVM vectorises: 4 (AVX2) or 8 (AVX-512)
# divisions, exponentials or logarithms at a time, where a row's five actions alone would not
# fill a vector (`policy.kernel_maths`).


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _divide(values, divisors, out):
    for i in range(values.size):
        out[i] = values[i] / divisors[i]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _exp_all(values):
    for i in range(values.size):
        values[i] = exp(values[i])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _log_all(values):
    for i in range(values.size):
        values[i] = log(values[i])


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _mixture_ratios(x, y, to_x, to_y):
    """x / m and y / m with m = (x + y) / 2, elementwise (1 where the numerator is 0: its KL
    term adds 0). The ratio, not a difference of logs, is what eq. 10's KL takes the log of:
    near a copy (x ≈ m) the difference cancels to its rounding, and the square root of eq. 10
    magnifies it."""
    for i in range(x.size):
        m = 0.5 * (x[i] + y[i])
        to_x[i] = x[i] / m if x[i] > 0 else 1.0
        to_y[i] = y[i] / m if y[i] > 0 else 1.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _entropy(p, log_p, start, n):
    """`maths.normalized_entropy` of the (renormalised) policy p[start : start + n], in [0, 1];
    0 for one action. Σ p log p with log p given: the same sum, one log per row, not per
    action."""
    if n == 1:
        return 0.0
    h = 0.0
    for a in range(start, start + n):
        if p[a] > 0:
            h -= p[a] * log_p[a]
    return min(max(h / math.log(n), 0.0), 1.0)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _standardise(q, start, n, z, z_start):
    """`blend.standardise` of the Q-vector q[start : start + n]: z-scores into
    z[z_start : z_start + n], the scale returned (z = 0 and scale 0 when flat)."""
    magnitude = 0.0
    for a in range(n):
        magnitude = max(magnitude, abs(q[start + a]))
    divisor = magnitude if magnitude > 0 else 1.0
    mean = 0.0
    for a in range(n):
        z[z_start + a] = q[start + a] / divisor
        mean += z[z_start + a]
    mean = mean / n
    squares = 0.0
    for a in range(z_start, z_start + n):
        z[a] = z[a] - mean
        squares += z[a] * z[a]
    std = math.sqrt(squares / n)
    if std <= FLAT_STD_RTOL:
        for a in range(z_start, z_start + n):
            z[a] = 0.0
        return 0.0
    unit = 1.0 / std  # std > FLAT_STD_RTOL: a finite reciprocal, multiplied
    for a in range(z_start, z_start + n):
        z[a] = z[a] * unit
    return std * magnitude


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bound(probs, q_task, pi_task, start, n, epsilon):
    """Eq. R1 (`regret_bound.bound_rows`) of the row at [start, start + n) of the flat `probs`,
    `q_task` and `pi_task`, in place: the actions within ε of the task's best share the task
    policy's mass on them as the blend says, every other action keeps its task probability;
    the task policy itself where the blend puts nothing on them."""
    lowest = _largest(q_task, start, n) - epsilon
    task_mass = 0.0
    blend_mass = 0.0
    for a in range(start, start + n):
        if q_task[a] >= lowest:
            task_mass += pi_task[a]
            blend_mass += probs[a]
    for a in range(start, start + n):
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
    row's blend.)

    In phases over all rows: each phase that takes exponentials or logarithms gathers its
    arguments from every row into one flat block and takes them in one loop, which LLVM
    vectorises (`policy.kernel_maths`); a row's five values alone would not fill a vector. The
    other phases go row by row. Every value depends on its own row only."""
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
    rows, pairs = n_rows * n_actions, n_rows * n_slots * n_actions  # flat sizes of the blocks
    # Flat working memory, one allocation (an allocation costs more than a row's arithmetic);
    # row b's policy at [b A, (b + 1) A), slot s of row b at [(b P + s) A, (b P + s + 1) A)
    work = np.empty(
        6 * rows + 2 * n_rows + 5 * pairs + n_rows * n_slots + (1 + n_slots) * n_actions
    )
    used = 0
    pi_task = work[used : used + rows]  # eq. 2's task policy of each row
    used += rows
    p_task = work[used : used + rows]  # the same renormalised, as `maths` sees a policy
    used += rows
    log_p = work[used : used + rows]  # its logarithm
    used += rows
    final = work[used : used + rows]  # the blended Q's Boltzmann policy
    used += rows
    row_divisors = work[used : used + rows]
    used += rows
    log_sums = work[used : used + n_rows]
    used += n_rows
    powers = work[used : used + n_rows]  # eq. 9's A^H
    used += n_rows
    pi_impact = work[used : used + pairs]  # each slot's impact policy
    used += pairs
    p_beside = work[used : used + pairs]  # the row's task policy beside each of its slots
    used += pairs
    to_task = work[used : used + 2 * pairs]  # log(p / m), then log(π / m): eq. 10's ratios
    to_impact = to_task[pairs:]
    used += 2 * pairs
    pair_divisors = work[used : used + pairs]
    used += pairs
    distances = work[used : used + n_rows * n_slots]
    used += n_rows * n_slots
    blended = work[used : used + rows]  # the blended Q of each row (q_out's rows)
    used += rows
    z = work[used:]  # z-scores: the task's, then each slot's
    q_flat = q_task.reshape(rows)  # the inputs flat, read with one index rule (no row views)
    q_slots = q_impact.reshape(pairs)

    # eq. 2, the task policy: its exponents, their exponentials, the sums and their logarithms
    for b in range(n_rows):
        _centre(q_flat, b * n_actions, n_actions, alpha[b], log_p, row_divisors)
    _divide(log_p, row_divisors, log_p)
    pi_task[:] = log_p
    _exp_all(pi_task)
    for b in range(n_rows):
        log_sums[b] = _sum_into(pi_task, b * n_actions, n_actions, row_divisors)
    _divide(pi_task, row_divisors, pi_task)
    for b in range(n_rows):
        log_sums[b] *= _sum_into(pi_task, b * n_actions, n_actions, row_divisors)
    _divide(pi_task, row_divisors, p_task)
    _log_all(log_sums)
    for b in range(n_rows):
        start = b * n_actions
        for a in range(start, start + n_actions):
            log_p[a] -= log_sums[b]  # log of the renormalised policy, finite where p = 0
        entropy_out[b] = _entropy(p_task, log_p, start, n_actions)
    if method == SL:
        for b in range(n_rows):
            weight_out[b] = 1.0
            for a in range(n_actions):
                q_out[b, a] = q_flat[b * n_actions + a]
                probs_out[b, a] = pi_task[b * n_actions + a]
        return
    if method == NAIL:  # the plain mean of the raw Q-vectors
        for b in range(n_rows):
            active = 0
            for s in range(n_slots):
                if mask[b, s]:
                    active += 1
            for a in range(n_actions):
                total = q_flat[b * n_actions + a]
                for s in range(n_slots):
                    if mask[b, s]:
                        total += q_slots[(b * n_slots + s) * n_actions + a]
                blended[b * n_actions + a] = total / (1.0 + active)
            for s in range(n_slots):
                partners_out[b, s] = (1.0 if mask[b, s] else 0.0) / max(active, 1)
            weight_out[b] = 1.0 / (1.0 + active)
    else:  # AAIL
        # eq. 2, each active impact policy (an inactive slot's: uniform, never read), divided
        # by its sum, then renormalised as `maths` sees a policy
        for b in range(n_rows):
            for s in range(n_slots):
                start = (b * n_slots + s) * n_actions
                if mask[b, s]:
                    _centre(q_slots, start, n_actions, alpha[b], pi_impact, pair_divisors)
                else:
                    for a in range(start, start + n_actions):
                        pi_impact[a] = 0.0
                        pair_divisors[a] = 1.0
                for a in range(n_actions):
                    p_beside[start + a] = p_task[b * n_actions + a]
        _divide(pi_impact, pair_divisors, pi_impact)
        _exp_all(pi_impact)
        for _ in range(2):
            for i in range(0, pairs, n_actions):
                _sum_into(pi_impact, i, n_actions, pair_divisors)
            _divide(pi_impact, pair_divisors, pi_impact)
        # eq. 10: KL(x ‖ m) in bits is Σ x log2(x / m) over x > 0 (inf where m underflowed)
        _mixture_ratios(p_beside, pi_impact, to_task, to_impact)
        _log_all(to_task)  # both blocks: to_impact is its second half
        for i in range(n_rows * n_slots):
            kl_task = 0.0  # KL(p ‖ m), in nats
            kl_impact = 0.0  # KL(π_s ‖ m)
            for a in range(i * n_actions, (i + 1) * n_actions):
                kl_task += p_beside[a] * to_task[a]
                kl_impact += pi_impact[a] * to_impact[a]
            distances[i] = min(max((0.5 * kl_task + 0.5 * kl_impact) * LOG2_E, 0.0), 1.0)
        for i in range(n_rows * n_slots):
            distances[i] = math.sqrt(distances[i])
        for i in range(n_rows):  # eq. 9's A^H, as an exponential (libm's pow costs 4 of them)
            powers[i] = entropy_out[i] * math.log(n_actions)
        _exp_all(powers)
        for b in range(n_rows):
            active = 0
            for s in range(n_slots):
                if mask[b, s]:
                    active += 1
            # eq. 9 on the task policy's normalised entropy; the task alone without a partner
            w_t = 1.0
            if active > 0 and n_actions > 1:
                w_t = 1.0 - powers[b] / n_actions
            weight_out[b] = w_t
            # eq. 10's distances of the active slots, then ŵ
            total = 0.0
            for s in range(n_slots):
                if mask[b, s]:
                    partners_out[b, s] = distances[b * n_slots + s]
                total += partners_out[b, s]
            for s in range(n_slots):
                if total > 0:
                    partners_out[b, s] = partners_out[b, s] / total
                else:  # every impact policy equals the task policy: equal shares
                    partners_out[b, s] = (1.0 if mask[b, s] else 0.0) / max(active, 1)
            # eq. 8, on the raw Q-vectors or on the standardised preferences and their scales
            row, slots = b * n_actions, b * n_slots * n_actions
            if not normalise:
                for a in range(n_actions):
                    mixed = 0.0  # Σ_i ŵ_i Q_i
                    for s in range(n_slots):
                        if mask[b, s]:
                            mixed += partners_out[b, s] * q_slots[slots + s * n_actions + a]
                    blended[row + a] = w_t * q_flat[row + a] + (1.0 - w_t) * mixed
            else:
                s_task = _standardise(q_flat, row, n_actions, z, 0)
                s_mixed = 0.0  # Σ_i ŵ_i s_i
                for s in range(n_slots):
                    if mask[b, s]:
                        s_mixed += partners_out[b, s] * _standardise(
                            q_slots, slots + s * n_actions, n_actions, z, (1 + s) * n_actions
                        )
                s_blend = w_t * s_task + (1.0 - w_t) * s_mixed
                for a in range(n_actions):
                    mixed = 0.0  # Σ_i ŵ_i z_i
                    for s in range(n_slots):
                        if mask[b, s]:
                            mixed += partners_out[b, s] * z[(1 + s) * n_actions + a]
                    blended[row + a] = s_blend * (w_t * z[a] + (1.0 - w_t) * mixed)
    # eq. 2 on the blended Q, then eq. R1 where bounded
    for b in range(n_rows):
        _centre(blended, b * n_actions, n_actions, alpha[b], final, row_divisors)
    _divide(final, row_divisors, final)
    _exp_all(final)
    for b in range(n_rows):
        _sum_into(final, b * n_actions, n_actions, row_divisors)
    _divide(final, row_divisors, final)
    for b in range(n_rows):
        start = b * n_actions
        if bounded:
            _bound(final, q_flat, pi_task, start, n_actions, epsilon[b])
        for a in range(n_actions):
            q_out[b, a] = blended[start + a]
            probs_out[b, a] = final[start + a]


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
