"""Types of the compiled row forward (policy/_row_forward.c); `policy.row_forward` is its interface."""

from collections.abc import Sequence

import numpy as np

VARIANT: str  # "avx512", "avx2" or "none" (no compiled forward on this machine)

def forward(
    x_XPF: np.ndarray,
    layers: Sequence[tuple[np.ndarray, np.ndarray]],
    start: int,
    members: int,
    activation: str,
    /,
) -> np.ndarray: ...
def set_variant(name: str, /) -> str: ...
def all_finite(a: np.ndarray, /) -> bool: ...
