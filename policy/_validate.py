"""Input checks shared by `policy.maths` and `policy.blend`.

Every check raises `ValueError` naming the argument and what was expected, so bad input from a
REST client or a trainer config surfaces as a readable message rather than a NaN further down.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

PROB_SUM_TOL = 1e-6  # how far a probability vector may sum away from 1


def float_array(x: ArrayLike, name: str) -> np.ndarray:
    """`x` as a float64 array, or a ValueError naming `name`."""
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected an array of real numbers ({exc})") from None


def require_actions(arr: np.ndarray, name: str) -> None:
    """The last axis is the action axis: it must exist and be non-empty."""
    if arr.ndim < 1 or arr.shape[-1] == 0:
        raise ValueError(
            f"{name}: expected shape (..., A) with at least one action, got shape {arr.shape}"
        )


def require_finite(arr: np.ndarray, name: str) -> None:
    if not np.isfinite(arr).all():
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ValueError(f"{name}: {bad} non-finite value(s) (NaN or inf) in shape {arr.shape}")


def q_array(q: ArrayLike, name: str) -> np.ndarray:
    """A finite float64 Q array of shape (..., A), A >= 1."""
    arr = float_array(q, name)
    require_actions(arr, name)
    require_finite(arr, name)
    return arr


def prob_array(p: ArrayLike, name: str) -> np.ndarray:
    """A probability array of shape (..., A), renormalised exactly along the last axis."""
    arr = q_array(p, name)
    if (arr < 0).any():
        raise ValueError(f"{name}: probabilities must be non-negative (shape {arr.shape})")
    total = arr.sum(axis=-1, keepdims=True)
    if (np.abs(total - 1.0) > PROB_SUM_TOL).any():
        worst = float(np.max(np.abs(total - 1.0)))
        raise ValueError(
            f"{name}: probabilities must sum to 1 along the last axis "
            f"(tolerance {PROB_SUM_TOL:g}); worst row is off by {worst:.3g}, shape {arr.shape}"
        )
    return arr / total


def alpha_array(alpha: ArrayLike, batch_shape: tuple[int, ...]) -> np.ndarray:
    """The temperature broadcast to `batch_shape + (1,)` (ready to divide a (..., A) array)."""
    arr = float_array(alpha, "alpha")
    if not np.isfinite(arr).all() or (arr <= 0).any():
        shown = repr(arr.tolist()) if arr.size <= 8 else f"an array of shape {arr.shape}"
        raise ValueError(f"alpha: expected a positive finite temperature, got {shown}")
    try:
        arr = np.broadcast_to(arr, batch_shape)
    except ValueError:
        raise ValueError(
            f"alpha: shape {arr.shape} does not broadcast to the batch shape {batch_shape}"
        ) from None
    return arr[..., None]
