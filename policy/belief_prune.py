"""Goal pruning: a belief update that skips the likelihood of improbable goals, with a bound on
the error that costs, checked at every step (`docs/method.md`, "Goal pruning").

Per row (one partner), with the notation of `policy.belief`: b the belief held (floored), ε the
floor, λ the forgetting, G goals. The exact update weighs goal g by

    w_g = exp(λ log b_g + (1 - λ) log prior_ε,g) · ℓ_g = p_g ℓ_g,   ℓ_g = π_g(a | s) in (0, 1],

normalises, b'_g = w_g / Σ w, and floors, b''_g = (1 - Gε) b'_g + ε. Pruning splits the goals
into the active set A (every goal whose probability is at least τ, and the most probable goal,
so A is never empty) and the pruned set S, and computes ℓ_g only on A. A pruned goal's weight
is unknown but bounded: ℓ_g <= 1 (a probability), so w_g <= p_g. The pruned update sets the
pruned goals' pre-floor probability to 0 and renormalises A:

    b^_g = w_g / W_A on A, 0 on S,  W_A = Σ_A w_g;  then the same floor.

Its total-variation distance to the exact update is exactly (1 - Gε) m, m = W_S / (W_A + W_S)
the pruned goals' true share (A gains exactly what S loses; the floor is an affine map that
scales differences by 1 - Gε), and m is at most

    β = P_S / (W_A + P_S),   P_S = Σ_S p_g:

the pruned goals' prior weight against the active goals' evidence. β is the pruned mass times
the likelihood ratio a pruned goal can win by: P_S / W_A = (P_S / P_A) / ℓ̄_A with ℓ̄_A the
active goals' mean likelihood of the action, and a pruned goal's ℓ_g / ℓ̄_A <= 1 / ℓ̄_A <=
A exp(ΔQ / α) for a task network whose Q-values span ΔQ at temperature α (its least likely
action still has probability >= exp(-ΔQ / α) / A). `bound` = (1 - Gε) β is computed from what
the pruned step scores anyway, and it is attained when every pruned goal gives the action
probability 1. The rule: a row is pruned only while its bound is at most δ; a row whose bound
exceeds δ (the active goals explain the action badly: a partner that changed its mind) gets its
pruned goals scored too, and the exact update.

Pure numpy, float64; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PrunedUpdate", "active_goals", "pruned_update"]


def active_goals(log_belief_EG: np.ndarray, threshold: float) -> np.ndarray:
    """The goals scored for rows `log_belief_EG` (E, G): those whose probability is at least
    `threshold` in some row, and each row's most probable goal; ascending indices (int64)."""
    log_b = np.asarray(log_belief_EG, dtype=np.float64)
    keep = (
        (log_b >= np.log(threshold)).any(axis=0) if threshold > 0 else np.ones(log_b.shape[1], bool)
    )
    keep[np.argmax(log_b, axis=1)] = True
    return np.flatnonzero(keep)


@dataclass(frozen=True, eq=False)
class PrunedUpdate:
    """`pruned_update`'s answer: the pruned update per row and each row's bound on its
    total-variation distance to the exact update ((1 - Gε) β, module docstring); a row whose
    bound is not finite (its evidence or update is not finite) must take the exact update."""

    log_belief_EG: np.ndarray
    bound_E: np.ndarray


def pruned_update(
    log_belief_EG: np.ndarray,
    log_lik_EA: np.ndarray,
    active: np.ndarray,
    pull_EG: np.ndarray | None,
    forgetting: float,
    floor: float,
) -> PrunedUpdate:
    """The pruned update of rows `log_belief_EG` (E, G) from the log-likelihoods `log_lik_EA`
    (E, len(active)) of the goals `active` (ascending indices, at least one), `pull_EG` the
    forgetting's prior term (1 - λ) log prior_ε (None at λ = 1), as `policy.belief`'s
    `PreparedUpdate` holds it. With every goal active it is the exact update (bound 0)."""
    log_b = np.asarray(log_belief_EG, dtype=np.float64)
    lik = np.asarray(log_lik_EA, dtype=np.float64)
    n_rows, n_goals = log_b.shape
    base = forgetting * log_b
    if pull_EG is not None:
        base = base + pull_EG
    x = base[:, active] + lik  # log w_g on A
    pruned = np.ones(n_goals, dtype=bool)
    pruned[active] = False
    with np.errstate(invalid="ignore", over="ignore"):
        log_w_a = _logsumexp(x)  # (E,)
        if pruned.any():
            log_p_s = _logsumexp(base[:, pruned])
            beta = np.exp(log_p_s - np.logaddexp(log_w_a, log_p_s))
        else:
            beta = np.zeros(n_rows)
        bound = (1.0 - n_goals * floor) * beta
        finite = np.isfinite(x).all(axis=1) & np.isfinite(log_w_a) & np.isfinite(bound)
        bound = np.where(finite, bound, np.inf)
        log_pre = np.full((n_rows, n_goals), -np.inf)
        log_pre[:, active] = x - log_w_a[:, None]
    if floor > 0:
        with np.errstate(divide="ignore", invalid="ignore"):  # rows without evidence: kept below
            log_new = np.logaddexp(np.log1p(-n_goals * floor) + log_pre, np.log(floor))
    else:
        log_new = log_pre
    log_new = np.where(finite[:, None], log_new, log_b)
    return PrunedUpdate(log_new, bound)


def _logsumexp(x: np.ndarray) -> np.ndarray:
    """log Σ exp(x) over the last axis, (E, K) -> (E,); rows of -inf give -inf."""
    top = x.max(axis=1)
    safe = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return safe + np.log(np.exp(x - safe[:, None]).sum(axis=1))
