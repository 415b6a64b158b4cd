"""The paper's per-state policy maths, as pure batched numpy functions (float64 inside).

| function              | paper  | input            | output | range      |
|-----------------------|--------|------------------|--------|------------|
| `soft_value`          | eq. 3  | q (..., A), α    | (...)  | ≥ max Q    |
| `boltzmann`           | eq. 2  | q (..., A), α    | (..., A) | simplex  |
| `normalized_entropy`  | §3.3   | π (..., A)       | (...)  | [0, 1]     |
| `js_distance`         | eq. 10 | p, q (..., A)    | (...)  | [0, 1]     |
| `task_weight`         | eq. 9  | π (..., A)       | (...)  | [0, 1 - 1/A] (1 if A = 1) |

Conventions:
- The last axis is the action axis A (A ≥ 1); any leading batch shape is allowed.
- `alpha` is a positive finite temperature: a scalar or an array broadcastable to the batch shape.
- Stability: every exponent is taken of (q - max q) / α ≤ 0, so α → 0 and |Q| ~ 1e300 give no
  overflow and no NaN; a Q-vector shifted by a constant gives the same policy.
- The normalised entropy divides by log |A|; with one action it is defined as 0 (the policy is
  certain), and the task weight of eq. 9 is defined as 1 (nothing to blend in).
- Jensen-Shannon *distance* is the square root of the JS divergence in base 2, so it lies in
  [0, 1]; rounding that makes the divergence slightly negative or above 1 is clipped.
- Bad input (alpha ≤ 0 or non-finite, non-finite Q, empty action axis, probabilities that are
  negative or do not sum to 1 within 1e-6) raises `ValueError` naming the argument.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from policy._validate import alpha_array, prob_array, q_array

__all__ = ["boltzmann", "js_distance", "normalized_entropy", "soft_value", "task_weight"]


def _scaled_advantage(q: np.ndarray, alpha: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q - max q) / α (all ≤ 0, max exactly 0), max q and α, all keeping the action axis."""
    a = alpha_array(alpha, q.shape[:-1])
    q_max = q.max(axis=-1, keepdims=True)
    with np.errstate(over="ignore"):  # a gap of 1e300 / 1e-9 is -inf: exp(-inf) = 0 is right
        return (q - q_max) / a, q_max, a


def soft_value(q_BA: ArrayLike, alpha: ArrayLike) -> np.ndarray:
    """Soft state value V = α log Σ_a exp(Q(a) / α), shape (...)."""
    q = q_array(q_BA, "q_BA")
    x, q_max, a = _scaled_advantage(q, alpha)
    # eq. 3, written as max Q + α log Σ exp((Q - max Q)/α) so it never overflows
    v = q_max + a * np.log(np.exp(x).sum(axis=-1, keepdims=True))
    return v[..., 0]


def boltzmann(q_BA: ArrayLike, alpha: ArrayLike) -> np.ndarray:
    """Boltzmann (soft-max) policy π(a) ∝ exp(Q(a) / α), shape (..., A)."""
    q = q_array(q_BA, "q_BA")
    x, _, _ = _scaled_advantage(q, alpha)
    e = np.exp(x)  # eq. 2; the arg-max action has exp(0) = 1, so the sum is ≥ 1
    return e / e.sum(axis=-1, keepdims=True)


def normalized_entropy(pi_BA: ArrayLike) -> np.ndarray:
    """Entropy of π divided by log |A| (the H_|A| of eq. 9), in [0, 1]; 0 when |A| = 1."""
    p = prob_array(pi_BA, "pi_BA")
    n_actions = p.shape[-1]
    if n_actions == 1:
        return np.zeros(p.shape[:-1])
    positive = p > 0
    p_log_p = np.where(positive, p * np.log(np.where(positive, p, 1.0)), 0.0)  # 0 log 0 = 0
    h = -p_log_p.sum(axis=-1) / np.log(n_actions)
    return np.clip(h, 0.0, 1.0)


def _kl_to_mixture_bits(p: np.ndarray, m: np.ndarray) -> np.ndarray:
    """KL(p ‖ m) in bits, where m ≥ p / 2 > 0 wherever p > 0."""
    positive = p > 0
    ratio = np.where(positive, p, 1.0) / np.where(positive, m, 1.0)
    return np.where(positive, p * np.log2(ratio), 0.0).sum(axis=-1)


def js_distance(p_BA: ArrayLike, q_BA: ArrayLike) -> np.ndarray:
    """Jensen-Shannon distance (base 2) between two policies, in [0, 1], shape (...).

    The batch shapes of `p_BA` and `q_BA` are broadcast against each other; the action counts
    must be equal.
    """
    p = prob_array(p_BA, "p_BA")
    q = prob_array(q_BA, "q_BA")
    if p.shape[-1] != q.shape[-1]:
        raise ValueError(
            f"p_BA and q_BA: action axes differ, shapes {p.shape} and {q.shape} (expected equal A)"
        )
    try:
        p, q = np.broadcast_arrays(p, q)
    except ValueError:
        raise ValueError(
            f"p_BA and q_BA: batch shapes do not broadcast, shapes {p.shape} and {q.shape}"
        ) from None
    m = 0.5 * (p + q)
    divergence = 0.5 * _kl_to_mixture_bits(p, m) + 0.5 * _kl_to_mixture_bits(q, m)
    return np.sqrt(np.clip(divergence, 0.0, 1.0))  # eq. 10: the distance, not the divergence


def task_weight(pi_BA: ArrayLike) -> np.ndarray:
    """Weight of the task policy w_t = 1 - |A|^H_|A|(π) / |A|, shape (...); 1 when |A| = 1."""
    p = prob_array(pi_BA, "pi_BA")
    n_actions = p.shape[-1]
    if n_actions == 1:
        return np.ones(p.shape[:-1])
    # eq. 9: |A|^H is the "effective number of actions" of π, from 1 (certain) to |A| (uniform)
    return 1.0 - np.power(float(n_actions), normalized_entropy(p)) / n_actions
