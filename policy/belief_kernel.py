"""A session's belief step compiled by numba: the update of `policy.belief.PreparedUpdate` (its
all-finite case), the numbers of `policy.belief_views.belief_views` (its whole-belief,
all-positive case), the goal likelihoods' log softmax table (`services.engine.goal_inference`)
and the expected impact Q of goal distributions (`services.engine.engine._impact_q`).

Why compiled: with G = 35 goals and a few partners the update and the views are ~25 small numpy
calls and Python loops over 35 floats; here they are loops over the rows.

The numpy code (`policy.belief`, `policy.belief_views`, `goal_inference`, `_impact_q`'s
einsum) is the reference; the steps below follow it with plain sums, so the results differ by
rounding: tests/policy/test_belief_kernel.py holds them to it within 1e-12. Rows outside the
cases above (a non-finite likelihood or update, a zero probability) are the numpy code's:
`update_rows` and `view_rows` say so, and `policy.belief_compiled` then takes the numpy path.
The signatures are explicit: compiled (or loaded from numba's cache) at import.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

from policy.blend_kernel import b1, f8, i8, in_array, out_array

LN2 = math.log(2.0)


@njit(cache=True, nogil=True, error_model="numpy")
def _logaddexp(x, c):
    """numpy's logaddexp(x, c): log(exp(x) + exp(c)) without overflow."""
    if x == c:
        return x + LN2
    if x > c:
        return x + math.log1p(math.exp(c - x))
    return c + math.log1p(math.exp(x - c))


@njit(
    types.Tuple((out_array(f8, 2), b1))(
        in_array(f8, 2), in_array(f8, 2), in_array(f8, 2), b1, f8, f8, b1, f8
    ),
    cache=True,
    nogil=True,
    error_model="numpy",
)
def update_rows(log_b, lik, pull, has_pull, lam, floor_scale, floored, floor_log):
    """(updated (E, G), done): `policy.belief._updated`'s all-finite case, per row
    x = lam log_b + lik (+ pull); z = x - (max x + log Σ exp(x - max x)); with a floor
    logaddexp(floor_scale + z, floor_log) (floor_scale = log1p(-G floor), floor_log =
    log(floor)). done False when a likelihood or an x is not finite (the numpy path's case)."""
    n_rows, n_goals = log_b.shape
    if lik.shape != log_b.shape or (has_pull and pull.shape != log_b.shape):
        raise ValueError("lik, pull: expected the shape of log_belief")
    out = np.empty((n_rows, n_goals))
    for e in range(n_rows):
        for g in range(n_goals):
            if not math.isfinite(lik[e, g]):
                return out, False
    for e in range(n_rows):
        x = out[e]
        for g in range(n_goals):
            x[g] = lam * log_b[e, g] + lik[e, g]
            if has_pull:
                x[g] = x[g] + pull[e, g]
            if not math.isfinite(x[g]):
                return out, False
        top = x.max()
        total = 0.0
        for g in range(n_goals):
            total += math.exp(x[g] - top)
        norm = top + math.log(total)
        for g in range(n_goals):
            z = x[g] - norm
            x[g] = _logaddexp(floor_scale + z, floor_log) if floored else z
    return out, True


@njit(
    types.Tuple((out_array(f8, 2), out_array(f8, 2), out_array(i8, 2), out_array(f8, 1), b1))(
        in_array(f8, 2), i8
    ),
    cache=True,
    nogil=True,
    error_model="numpy",
)
def view_rows(log_b, k):
    """(probs, blend_probs, top (E, min(k, G)), entropy, usable) of the rows: `belief_views`'
    numbers where every probability is > 0 and the whole belief is blended: b = exp(log_b),
    blend_probs = b / Σ b, the k most probable goals (the first k of the stable order of
    -log b), entropy = max(0, -Σ b log b). usable False, and the rest unfinished, where a row
    has a zero probability (the caller takes the numpy path)."""
    n_rows, n_goals = log_b.shape
    if k < 1:
        raise ValueError("k: expected >= 1")
    top_k = min(k, n_goals)
    probs = np.exp(log_b)
    blend = np.empty((n_rows, n_goals))
    top = np.empty((n_rows, top_k), dtype=np.int64)
    entropy = np.zeros(n_rows)
    taken = np.empty(n_goals, dtype=np.bool_)
    for e in range(n_rows):
        p, row = probs[e], log_b[e]
        h = 0.0
        total = 0.0
        for g in range(n_goals):
            if not p[g] > 0:
                return probs, blend, top, entropy, False
            h += p[g] * row[g]
            total += p[g]
        entropy[e] = max(0.0, -h)
        for g in range(n_goals):
            blend[e, g] = p[g] / total
        # the stable descending order's first k: the largest log b not yet taken, the lowest
        # index among equals (what argsort(-log_b, kind="stable") puts first)
        taken[:] = False
        for j in range(top_k):
            best = -1
            for g in range(n_goals):
                if not taken[g] and (best < 0 or row[g] > row[best]):
                    best = g
            taken[best] = True
            top[e, j] = best
    return probs, blend, top, entropy, True


@njit(
    out_array(f8, 3)(in_array(types.float32, 3), in_array(f8, 1)),
    cache=True,
    nogil=True,
    error_model="numpy",
)
def log_softmax_table(q, alpha):
    """log softmax(Q / α_g) of every (G, P, A) row, float64, as `goal_inference._scaled` and
    the subtraction after it compute it: z = (float64(q) - max q) / α_g, then z - log Σ exp z.
    Q-values finite (the caller checks)."""
    n_goals, n_rows, n_actions = q.shape
    out = np.empty((n_goals, n_rows, n_actions))
    for g in range(n_goals):
        for p in range(n_rows):
            z = out[g, p]
            top = np.float64(q[g, p, 0])
            for a in range(1, n_actions):
                top = max(top, np.float64(q[g, p, a]))
            total = 0.0
            for a in range(n_actions):
                z[a] = (np.float64(q[g, p, a]) - top) / alpha[g]
                total += math.exp(z[a])
            log_norm = math.log(total)
            for a in range(n_actions):
                z[a] = z[a] - log_norm
    return out


@njit(
    out_array(f8, 3)(in_array(types.float32, 2), in_array(i8, 2), in_array(f8, 2), i8),
    cache=True,
    nogil=True,
    error_model="numpy",
)
def mix_goals(q, units, probs, batch):
    """(B, P, A) float64: P goal distributions' expected Q (§3.2), out[b, p] = Σ_g
    probs[p, g] q[units[p, g] B + b] in goal order (`_impact_q`'s einsum); unit u's B rows
    are q's rows u B .. u B + B - 1."""
    n_partners, n_goals = units.shape
    n_actions = q.shape[1]
    if batch < 1 or probs.shape[0] != n_partners or probs.shape[1] != n_goals:
        raise ValueError("mix_goals: expected batch >= 1 and probs of the shape of units_PG")
    for p in range(n_partners):
        for g in range(n_goals):
            if units[p, g] < 0 or (units[p, g] + 1) * batch > q.shape[0]:
                raise ValueError("units_PG: a unit outside q_RA's rows")
    out = np.zeros((batch, n_partners, n_actions))
    for p in range(n_partners):
        for g in range(n_goals):
            weight = probs[p, g]
            first = units[p, g] * batch
            for b in range(batch):
                for a in range(n_actions):
                    out[b, p, a] += weight * np.float64(q[first + b, a])
    return out
