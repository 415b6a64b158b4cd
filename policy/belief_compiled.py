"""The compiled belief step (policy/_belief_row.c) behind `policy.belief`'s update and
`policy.belief_views.belief_views`, the goal likelihoods' table of
`services.engine.goal_inference` and the expected impact Q of goal distributions
(`services.engine.engine._impact_q`): C loops over the rows instead of ~25 small numpy calls. The
numpy code is the reference; the compiled results agree with it within 1e-12
(tests/policy/test_belief_compiled.py). Each function answers None where the compiled code
does not apply (or is not built), and the caller then runs its numpy path:

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
from typing import Any, NamedTuple

import numpy as np

from policy._kernels import load_kernel

MAX_TOP = 64  # top goals the compiled views list at most (policy/_belief_row.c)


class BeliefView(NamedTuple):
    """What a session reads from one belief row at every step (`belief_views`)."""

    blend_goals: list[int]  # `blend_goal_weights`' kept goals (ascending indices)
    blend_probs: list[float]  # and their probabilities
    top: list[tuple[str, float]]  # `belief_summary`'s top goals
    entropy: float  # and entropy


# policy/_belief_row.c, built by setup.py where a C compiler exists
_EXTENSION: Any = load_kernel("_belief_row")
COMPILED = _EXTENSION is not None


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
    if _EXTENSION is None or lik.shape != log_b.shape:
        return None
    if pull is not None and pull.shape != log_b.shape:
        pull = np.broadcast_to(pull, log_b.shape)  # one prior for every row
    pull_rows = None if pull is None else _rows(pull)
    floor_log = math.log(eps) if eps else None  # `_apply_floor`: no floor at 0
    floor_scale = math.log1p(-log_b.shape[-1] * eps)
    out = _EXTENSION.update_rows(_rows(log_b), _rows(lik), pull_rows, lam, floor_scale, floor_log)
    return None if out is None else out.reshape(log_b.shape)


def compiled_views(log_b: np.ndarray, goals: Sequence[str], k: int) -> list[BeliefView] | None:
    """`belief_views(log_b, goals, k)` of a whole-belief blend compiled, or None (module
    docstring); `log_b` (P, G) float64, checked by the caller."""
    if _EXTENSION is None or k > MAX_TOP:
        return None
    rows = _EXTENSION.view_rows(np.ascontiguousarray(log_b), k)
    if any(row is None for row in rows):
        return None
    n_goals = log_b.shape[1]
    return [
        BeliefView(list(range(n_goals)), blend, [(goals[g], probs[g]) for g in top], entropy)
        for probs, blend, top, entropy in rows
    ]


def compiled_log_softmax(q_GPA: np.ndarray, alpha: np.ndarray | float) -> np.ndarray | None:
    """log softmax(q / α_g) over the last axis of a (G, P, A) float32 array, float64, as
    `services.engine.goal_inference` computes it with numpy (`alpha` a float or G values in
    any shape), or None without the extension."""
    if _EXTENSION is None or q_GPA.dtype != np.float32 or not q_GPA.flags.c_contiguous:
        return None
    if isinstance(alpha, np.ndarray):
        alpha = np.ascontiguousarray(alpha, dtype=np.float64).reshape(-1)
    result: np.ndarray = _EXTENSION.log_softmax_table(q_GPA, alpha)
    return result


def compiled_mix_goals(
    q_RA: np.ndarray, units_PG: np.ndarray, probs: Sequence[Sequence[float]], batch: int
) -> np.ndarray | None:
    """(B, P, A) float64: each of P goal distributions' expected Q (§3.2), out[b, p] = sum over
    g of probs[p][g] * q_RA[units_PG[p, g] * batch + b] (`_impact_q`'s einsum), or None
    (module docstring). `units_PG` intp (P, G), C-contiguous."""
    if _EXTENSION is None or q_RA.dtype != np.float32 or not q_RA.flags.c_contiguous:
        return None
    result: np.ndarray = _EXTENSION.mix_goals(q_RA, units_PG, probs, batch)
    return result
