"""SL / NAIL / AAIL (§3.3, eqs. 8-10) one row at a time: the numbers of `policy.blend`'s
vectorised path without numpy's per-call overhead, which dominates tiny arrays (one AAIL row of
4 partners and 5 actions: ~35 µs in Python, ~2.5 µs compiled, against ~160 µs vectorised).

`blend_row_python` is the reference, in plain Python; `policy/_blend_row.c` compiles the same
steps (setup.py builds it where a C compiler exists) and `blend_row` uses it when present
(`COMPILED`; COEXIST_PYTHON_BLEND=1 forces the reference). Tests hold both to the same bits.
Compiled matters most in a server: between requests the networks' weights stream through the
CPU caches, and the Python blend then ran at 60-100 µs, most of a single act's engine time.

Inputs are trusted (the caller validated them): finite Q-values, alpha > 0, vectors of one
length A >= 1; masked partner slots are never read.

| argument       | type                     | meaning                                            |
|----------------|--------------------------|----------------------------------------------------|
| `q_task_A`     | A floats                 | the ego's task network Q_t                         |
| `q_impact_PA`  | P vectors of A floats    | one impact Q_i per partner slot (P may be 0)       |
| `alpha`        | float                    | Boltzmann temperature                              |
| `mask_P`       | P bools, or None         | which slots hold a partner (None: all)             |

The semantics (standardisation and scale rule, Σw = 0 fallback, rows without partners, one
action) are `policy.blend`'s and documented there. The arithmetic follows the vectorised path
operation by operation so that both give the same bits. That matters where the result is
ill-conditioned: the JS distance of two nearly equal policies is mostly rounding, and the
z-scores of a nearly flat Q-vector amplify the rounding of its mean.

- A sum over actions or over partner weights is numpy's pairwise sum (`np_sum`); eq. 8's sum
  over partners and NAIL's are sequential, as numpy's einsum and axis-1 sum are.
- exp, log, log2 and power are numpy's ufuncs (its SIMD versions can differ from `math` in the
  last bit), called as `policy.maths` calls them; + - * / and sqrt are exact in both.
- Probabilities are renormalised where `policy.maths` renormalises them (entropy, JSD, eq. 9).
- `zip(..., strict=False)` in the inner loops: lengths are equal by construction, and the
  strict check costs half of a 5-element comprehension.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Callable, Iterable, Sequence
from functools import cache
from operator import mul, truediv
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from policy.regret_bound import bound_row

if TYPE_CHECKING:
    from policy.blend import BlendMethod

__all__ = [
    "COMPILED",
    "FLAT_STD_RTOL",
    "RowBlend",
    "blend_row",
    "blend_row_python",
    "compiled_rows",
    "np_sum",
]

FLAT_STD_RTOL = 1e-12  # a Q-vector whose std is below this fraction of max |Q| is "flat"
_PAIRWISE_BLOCK = 128  # numpy's PW_BLOCKSIZE

Vector = Sequence[float]
Summer = Callable[[Sequence[float]], float]


class RowBlend(NamedTuple):
    """One row of `policy.blend.BlendResult`, as Python floats."""

    q_A: list[float]  # blended Q used for the final policy
    probs_A: list[float]  # Boltzmann(q_A, alpha)
    task_entropy: float  # normalised entropy of the task policy
    task_weight: float  # w_t: 1 (SL), 1/(1+P_active) (NAIL), eq. 9 (AAIL)
    partner_weights_P: list[float]  # ŵ_i per slot, 0 for masked slots


def _loop_sum(xs: Iterable[float]) -> float:
    total = 0.0
    for x in xs:
        total += x
    return total


# CPython < 3.12 `sum` adds floats one after the other (3.12 compensates: other bits)
_sequential_sum: Callable[[Iterable[float]], float] = (
    sum if sys.version_info < (3, 12) else _loop_sum
)


def np_sum(xs: Vector) -> float:
    """Sum in numpy's order for a contiguous reduction (pairwise, 8 accumulators per block)."""
    n = len(xs)
    if n < 8:
        return _sequential_sum(xs)
    if n <= _PAIRWISE_BLOCK:
        acc = list(xs[:8])
        stop = n - n % 8
        for i in range(8, stop, 8):
            for j in range(8):
                acc[j] += xs[i + j]
        total = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
        for x in xs[stop:]:
            total += x
        return total
    half = n // 2
    half -= half % 8
    return np_sum(xs[:half]) + np_sum(xs[half:])


@cache
def _log(n: int) -> float:
    return float(np.log(n))  # log |A| as `maths.normalized_entropy` computes it


def _boltzmann(vectors: Sequence[Vector], alpha: float, vsum: Summer) -> list[list[float]]:
    """eq. 2 for each vector, in `maths.boltzmann`'s steps, with one numpy exp for all."""
    tops = [max(q) for q in vectors]
    # (q - max q) / α <= 0 (-inf on overflow: exp gives 0)
    flat = [(x - top) / alpha for q, top in zip(vectors, tops, strict=False) for x in q]
    exps = np.exp(flat).tolist()
    n = len(vectors[0])
    out = []
    for start in range(0, len(exps), n):
        e = exps[start : start + n]
        total = vsum(e)
        out.append([x / total for x in e])
    return out


def _renormalised(p: list[float], vsum: Summer) -> list[float]:
    """`maths.prob_array`'s division by the sum (x / 1.0 is x: no copy then)."""
    total = vsum(p)
    return p if total == 1.0 else [x / total for x in p]


def _entropies(policies: list[list[float]], vsum: Summer) -> list[float]:
    """`maths.normalized_entropy` of each policy (one numpy log for all)."""
    n = len(policies[0])
    if n == 1:
        return [0.0] * len(policies)
    logs = np.log([x if x > 0 else 1.0 for p in policies for x in p]).tolist()
    out = []
    for start, p in zip(range(0, len(logs), n), policies, strict=False):
        log_p = logs[start : start + n]
        h = -vsum([x * lg if x > 0 else 0.0 for x, lg in zip(p, log_p, strict=False)]) / _log(n)
        out.append(min(max(h, 0.0), 1.0))
    return out


def _js_distances(p: list[float], partners: list[list[float]], vsum: Summer) -> list[float]:
    """eq. 10: the Jensen-Shannon distance (base 2) of p to each policy, as `maths.js_distance`
    computes it: KL(p ‖ m) and KL(q ‖ m) in bits with m = (p + q) / 2, one numpy log2."""
    n = len(p)
    p_rep = p * len(partners)
    q_flat = [x for q in partners for x in q]
    m = [0.5 * (x + y) for x, y in zip(p_rep, q_flat, strict=False)]
    num, den = p_rep + q_flat, m + m
    regular = min(num) > 0 and min(m) > 0  # no zero probability, no underflowed mixture
    if regular:
        ratios = list(map(truediv, num, den))
    else:  # numpy: 1 where the numerator is 0 (the term is 0), inf where m underflowed to 0
        ratios = [
            (x / y if y > 0 else math.inf) if x > 0 else 1.0 for x, y in zip(num, den, strict=False)
        ]
    log2s = np.log2(ratios).tolist()
    if regular:
        terms = list(map(mul, num, log2s))
    else:
        terms = [x * lr if x > 0 else 0.0 for x, lr in zip(num, log2s, strict=False)]
    half = len(p_rep)
    out = []
    for start in range(0, half, n):
        kl_p, kl_q = vsum(terms[start : start + n]), vsum(terms[half + start : half + start + n])
        out.append(math.sqrt(min(max(0.5 * kl_p + 0.5 * kl_q, 0.0), 1.0)))
    return out


def _standardise(q: Vector, vsum: Summer) -> tuple[list[float], float]:
    """`policy.blend.standardise` of one vector: (z, scale); z = 0 and scale 0 when flat."""
    n = len(q)
    magnitude = max(max(q), -min(q))  # max |q|
    # divide by max |q| first so that the squares cannot overflow for |Q| ~ 1e300
    unit = [x / (magnitude if magnitude > 0 else 1.0) for x in q]
    mean = vsum(unit) / n
    deviation = [x - mean for x in unit]
    std = math.sqrt(vsum(list(map(mul, deviation, deviation))) / n)
    if std <= FLAT_STD_RTOL:  # no preference
        return [0.0] * n, 0.0
    return [d / std for d in deviation], std * magnitude


def blend_row_python(
    method: BlendMethod,
    q_task_A: Vector,
    q_impact_PA: Sequence[Vector],
    alpha: float,
    mask_P: Sequence[bool] | None = None,
    normalise: bool = True,
) -> RowBlend:
    """`policy.blend.blend` of one row, on trusted inputs (module docstring): the reference
    that `policy._blend_row` compiles."""
    alpha = float(alpha)  # a numpy float32 would turn the Python floats below into float32
    n_act = len(q_task_A)
    vsum: Summer = _sequential_sum if n_act < 8 else np_sum
    mask = [True] * len(q_impact_PA) if mask_P is None else list(mask_P)
    active = [q for q, on in zip(q_impact_PA, mask, strict=True) if on]
    if method == "aail":  # the Boltzmann policies of the task and of every active impact
        policies = _boltzmann([q_task_A, *active], alpha, vsum)
    else:
        policies = _boltzmann([q_task_A], alpha, vsum)
    pi_task = policies[0]
    p_once = _renormalised(pi_task, vsum)  # as `maths.normalized_entropy` sees it
    if method == "sl":
        [entropy] = _entropies([p_once], vsum)
        return RowBlend(list(q_task_A), pi_task, entropy, 1.0, [0.0] * len(mask))
    if method == "nail":
        [entropy] = _entropies([p_once], vsum)
        return _nail(q_task_A, q_impact_PA, alpha, mask, active, entropy, vsum)
    p_twice = _renormalised(p_once, vsum)  # as eq. 9 (`maths.task_weight`) sees it
    if p_twice is p_once:
        [entropy] = _entropies([p_once], vsum)
        h_eq9 = entropy
    else:
        entropy, h_eq9 = _entropies([p_once, p_twice], vsum)
    # eq. 9, w_t = 1 - |A|^H / |A|, with a scalar base as `maths.task_weight` calls it
    power = float(np.power(float(n_act), np.array([h_eq9]))[0])
    w_eq9 = 1.0 - power / n_act if n_act > 1 else 1.0
    impact_pis = [_renormalised(p, vsum) for p in policies[1:]]
    jsd = _js_distances(p_once, impact_pis, vsum) if impact_pis else []
    return _aail(q_task_A, q_impact_PA, alpha, mask, jsd, entropy, w_eq9, vsum, normalise)


def _nail(
    q_task_A: Vector,
    q_impact_PA: Sequence[Vector],
    alpha: float,
    mask: list[bool],
    active: list[Vector],
    entropy: float,
    vsum: Summer,
) -> RowBlend:
    """The raw mean of the task and the active impact Q-vectors (paper §4.2)."""
    if len(q_task_A) == 1:  # numpy then sums over the contiguous partner axis: pairwise
        slots = zip(q_impact_PA, mask, strict=True)
        summed = [np_sum([q[0] if on else 0.0 for q, on in slots])]
    else:  # numpy adds the partners' vectors one after the other
        summed = [0.0] * len(q_task_A)
        for q in active:
            summed = [s + x for s, x in zip(summed, q, strict=False)]
    n = len(active)
    q_blend = [(t + s) / (1.0 + n) for t, s in zip(q_task_A, summed, strict=False)]
    weights = [1.0 / max(n, 1) if on else 0.0 for on in mask]
    [probs] = _boltzmann([q_blend], alpha, vsum)
    return RowBlend(q_blend, probs, entropy, 1.0 / (1.0 + n), weights)


def _aail(
    q_task_A: Vector,
    q_impact_PA: Sequence[Vector],
    alpha: float,
    mask: list[bool],
    jsd: list[float],
    entropy: float,
    w_eq9: float,
    vsum: Summer,
    normalise: bool = True,
) -> RowBlend:
    """eqs. 8-10 given the JS distances of the active partners and the eq. 9 weight."""
    n_active = len(jsd)
    jsd_of = iter(jsd)
    w_slot = [next(jsd_of) if on else 0.0 for on in mask]
    total = np_sum(w_slot)
    if total > 0:
        w_hat = [w / total for w in w_slot]
    else:  # every impact policy equals the task policy: equal shares
        w_hat = [1.0 / max(n_active, 1) if on else 0.0 for on in mask]
    w_t = w_eq9 if n_active > 0 else 1.0  # no partner: the task alone
    if not normalise:  # eq. 8 on the raw Q-vectors
        return _aail_raw(q_task_A, q_impact_PA, alpha, mask, entropy, w_t, w_hat, vsum)

    z_task, s_task = _standardise(q_task_A, vsum)
    z_active, w_active = [], []
    scales = [0.0] * len(mask)  # masked slots: z = 0 and scale 0, as for a zeroed Q-vector
    for slot, (q, on) in enumerate(zip(q_impact_PA, mask, strict=True)):
        if on:
            z, scales[slot] = _standardise(q, vsum)
            z_active.append(z)
            w_active.append(w_hat[slot])
    # Σ_i ŵ_i z_i one action at a time, partners in order (numpy's einsum order)
    mixed_z = [_sequential_sum(map(mul, w_active, zs)) for zs in zip(*z_active, strict=True)]
    if not z_active:
        mixed_z = [0.0] * len(q_task_A)
    # eq. 8 on the standardised preferences, then the same weights on the scales
    z_blend = [w_t * zt + (1.0 - w_t) * zm for zt, zm in zip(z_task, mixed_z, strict=False)]
    s_blend = w_t * s_task + (1.0 - w_t) * np_sum(list(map(mul, w_hat, scales)))
    q_blend = [s_blend * z for z in z_blend]
    [probs] = _boltzmann([q_blend], alpha, vsum)
    return RowBlend(q_blend, probs, entropy, w_t, w_hat)


def _aail_raw(
    q_task_A: Vector,
    q_impact_PA: Sequence[Vector],
    alpha: float,
    mask: list[bool],
    entropy: float,
    w_t: float,
    w_hat: list[float],
    vsum: Summer,
) -> RowBlend:
    """eq. 8 without normalisation: Q_C = w_t Q_t + (1 - w_t) Σ_i ŵ_i Q_i."""
    active = [(q, w) for q, w, on in zip(q_impact_PA, w_hat, mask, strict=True) if on]
    # Σ_i ŵ_i Q_i one action at a time, partners in order (numpy's einsum order)
    mixed = [_sequential_sum(w * q[a] for q, w in active) for a in range(len(q_task_A))]
    if not active:
        mixed = [0.0] * len(q_task_A)
    q_blend = [w_t * qt + (1.0 - w_t) * qm for qt, qm in zip(q_task_A, mixed, strict=True)]
    [probs] = _boltzmann([q_blend], alpha, vsum)
    return RowBlend(q_blend, probs, entropy, w_t, w_hat)


_compiled: Any = None
_compiled_rows: Any = None
try:  # the same steps compiled (policy/_blend_row.c; setup.py builds it when a compiler exists)
    from policy import _blend_row

    _blend_row.set_result_type(RowBlend)
    _compiled, _compiled_rows = _blend_row.blend_row, _blend_row.blend_rows
except ImportError:  # pragma: no cover - an install without a C compiler
    pass

# COEXIST_PYTHON_BLEND=1 serves with the Python row blend (for an A/B; the numbers are the same)
COMPILED = _compiled is not None and os.environ.get("COEXIST_PYTHON_BLEND", "") in ("", "0")


def blend_row(
    method: BlendMethod,
    q_task_A: Vector,
    q_impact_PA: Sequence[Vector],
    alpha: float,
    mask_P: Sequence[bool] | None = None,
    normalise: bool = True,
    regret_bound: float | None = None,
) -> RowBlend:
    """`policy.blend.blend` of one row, on trusted inputs (module docstring; `aail_bounded`
    with a checked `regret_bound`): compiled when `COMPILED`, else `blend_row_python`; the same
    bits (`aail_bounded`'s bound itself equal to rounding, `policy.regret_bound`)."""
    base: BlendMethod = "aail" if method == "aail_bounded" else method
    if COMPILED:
        result: RowBlend = _compiled(base, q_task_A, q_impact_PA, alpha, mask_P, normalise)
    else:
        result = blend_row_python(base, q_task_A, q_impact_PA, alpha, mask_P, normalise)
    if method != "aail_bounded" or regret_bound is None:
        return result
    return result._replace(probs_A=bound_row(result.probs_A, q_task_A, alpha, regret_bound))


def compiled_rows(
    method: BlendMethod,
    q_task_BA: np.ndarray,
    q_impact_BPA: np.ndarray,
    alpha_B: np.ndarray,
    mask_BP: np.ndarray,
    *,
    normalise: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`blend_row` of every row in one compiled call (needs `COMPILED`): `policy.blend`'s
    BlendResult fields as float64 arrays, (q_BA, probs_BA, task_entropy_B, task_weight_B,
    partner_weights_BP). Inputs are trusted as `blend_row`'s are (`policy.blend` checks them)."""
    if _compiled_rows is None:
        raise RuntimeError("policy._blend_row is not built: use policy.blend.blend")
    arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] = _compiled_rows(
        method, q_task_BA, q_impact_BPA, alpha_B, mask_BP, normalise
    )
    return arrays
