"""Types of the compiled row forward (policy/_row_forward.c); `policy.row_forward` is its interface."""

from collections.abc import Sequence

import numpy as np

AVAILABLE: bool  # whether this CPU has AVX2 and FMA (otherwise `forward` raises)
WIDEST: int  # floats per vector: 16 where the CPU has AVX-512F, 8 with AVX2 only, 0 without

def forward(
    x_XPF: np.ndarray,
    layers: Sequence[tuple[np.ndarray, np.ndarray]],
    start: int,
    members: int,
    activation: str,
    lanes: int = 0,
    /,
) -> np.ndarray: ...
def mean_views(q_RA: np.ndarray, views: int, /) -> np.ndarray: ...
