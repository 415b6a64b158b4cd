"""Types of the compiled row forward (policy/_row_forward.c); `policy.row_forward` is its interface."""

from collections.abc import Sequence

import numpy as np

AVAILABLE: bool  # whether this CPU has AVX2 and FMA (otherwise `forward` raises)

def forward(
    x_XPF: np.ndarray,
    layers: Sequence[tuple[np.ndarray, np.ndarray]],
    start: int,
    members: int,
    activation: str,
    /,
) -> np.ndarray: ...
def mean_views(q_RA: np.ndarray, views: int, /) -> np.ndarray: ...
