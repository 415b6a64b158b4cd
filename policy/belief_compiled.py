"""The compiled belief step (`policy.belief_kernel`, numba) behind `policy.belief`'s update and
`policy.belief_views.belief_views`, the goal likelihoods' table of
`services.engine.goal_inference` and the expected impact Q of goal distributions
(`services.engine.engine._impact_q`): loops over the rows instead of ~25 small numpy calls. The
numpy code is the reference; the compiled results agree with it within 1e-12
(tests/policy/test_belief_compiled.py). Each function answers None where the compiled code
does not apply (the rows it leaves to the numpy code: non-finite values, a zero probability),
and the caller then runs its numpy path for them:

| function               | compiled when                                       | else  |
|------------------------|-----------------------------------------------------|-------|
| `compiled_update`      | every likelihood and every updated entry is finite  | None  |
| `compiled_views`       | the blend keeps every goal and every probability > 0| None  |
| `compiled_log_softmax` | always (finite Q-values: the caller checks)         | None  |
| `compiled_mix_goals`   | the Q-values are C-contiguous float32 (R, A)        | None  |
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from policy import belief_kernel


class BeliefView(NamedTuple):
    """What a session reads from one belief row at every step (`belief_views`)."""

    blend_goals: list[int]  # `blend_goal_weights`' kept goals (ascending indices)
    blend_probs: list[float]  # and their probabilities
    top: list[tuple[str, float]]  # `belief_summary`'s top goals
    entropy: float  # and entropy


_NO_PULL = np.zeros((0, 0))


def _rows(array: np.ndarray) -> np.ndarray:
    """(E, G) C-contiguous float64: the array itself when it is one already (the usual case)."""
    if array.ndim == 2 and array.dtype == np.float64 and array.flags.c_contiguous:
        return array
    return np.ascontiguousarray(array, dtype=np.float64).reshape(-1, array.shape[-1])


def compiled_update(
    log_b: np.ndarray, lik: np.ndarray, pull: np.ndarray | None, lam: float, eps: float
) -> np.ndarray | None:
    """`policy.belief._updated(log_b, lik, pull, lam, eps)` compiled, or None (module
    docstring). Shapes as `_updated` takes them: (G,) or (E, G), `pull` broadcasting."""
    if lik.shape != log_b.shape:
        return None
    if pull is not None and pull.shape != log_b.shape:
        pull = np.broadcast_to(pull, log_b.shape)  # one prior for every row
    floor_log = math.log(eps) if eps else 0.0  # `_apply_floor`: no floor at 0
    floor_scale = math.log1p(-log_b.shape[-1] * eps)
    out, done = belief_kernel.update_rows(
        _rows(log_b),
        _rows(lik),
        _NO_PULL if pull is None else _rows(pull),
        pull is not None,
        lam,
        floor_scale,
        bool(eps),
        floor_log,
    )
    return out.reshape(log_b.shape) if done else None


def compiled_views(log_b: np.ndarray, goals: Sequence[str], k: int) -> list[BeliefView] | None:
    """`belief_views(log_b, goals, k)` of a whole-belief blend compiled, or None (module
    docstring); `log_b` (P, G) float64, checked by the caller."""
    probs, blend, top, entropy, usable = belief_kernel.view_rows(np.ascontiguousarray(log_b), k)
    if not usable:
        return None
    every_goal = list(range(log_b.shape[1]))
    return [
        BeliefView(every_goal.copy(), blend_row, [(goals[g], row[g]) for g in top_row], h)
        for row, blend_row, top_row, h in zip(
            probs.tolist(), blend.tolist(), top.tolist(), entropy.tolist(), strict=True
        )
    ]


def compiled_log_softmax(q_GPA: np.ndarray, alpha: np.ndarray | float) -> np.ndarray | None:
    """log softmax(q / α_g) over the last axis of a (G, P, A) float32 array, float64, as
    `services.engine.goal_inference` computes it with numpy (`alpha` a float or G values in
    any shape), or None where `q_GPA` is not C-contiguous float32."""
    if q_GPA.dtype != np.float32 or not q_GPA.flags.c_contiguous:
        return None
    alpha_G = np.ascontiguousarray(alpha, dtype=np.float64).reshape(-1)
    if alpha_G.size != q_GPA.shape[0]:
        alpha_G = np.full(q_GPA.shape[0], alpha_G)  # one α for every goal
    result: np.ndarray = belief_kernel.log_softmax_table(q_GPA, alpha_G)
    return result


def compiled_mix_goals(
    q_RA: np.ndarray, units_PG: np.ndarray, probs: Sequence[Sequence[float]], batch: int
) -> np.ndarray | None:
    """(B, P, A) float64: each of P goal distributions' expected Q (§3.2), out[b, p] = sum over
    g of probs[p][g] * q_RA[units_PG[p, g] * batch + b] (`_impact_q`'s einsum), or None
    where `q_RA` is not C-contiguous float32. `units_PG` intp (P, G)."""
    if q_RA.dtype != np.float32 or not q_RA.flags.c_contiguous:
        return None
    units = np.ascontiguousarray(units_PG, dtype=np.int64)
    probs_PG = np.array(probs, dtype=np.float64).reshape(units.shape)
    result: np.ndarray = belief_kernel.mix_goals(q_RA, units, probs_PG, batch)
    return result
