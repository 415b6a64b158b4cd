"""A stack of small Q-networks, each on a few input rows: the inference engine's forward at
small batches.

    q_MPA = row_forward(x_XPF, layers, start, members, "relu")

`layers` holds per layer a weight stack (R, in, out) and a bias stack (R, 1, out), float32 (the
`row_weights` of `services.engine.networks.Partition`); member m < `members` is network
`start + m` of the stack and runs on the rows x[m] (X = members) or x[0] (X = 1: every member
on the same P rows). The result is (members, P, A) float32: hidden layers take the activation,
the last one is linear (as `policy.qnet.numpy_stacked_forward`).

`numpy_row_forward` is the reference: numpy's stacked matmul, one BLAS call per layer.
`policy/_row_forward.c` (built by setup.py) computes the same with one loop over the members
that loads each weight once per block of up to 4 rows, with AVX2 and FMA, or on 16-float
AVX-512 vectors in blocks of up to 8 rows where the CPU has them (`vector_widths`; both widths
give the same bits, and `lanes` picks one for a comparison); `row_forward` takes it where it
is built and the CPU has AVX2 and FMA (`COMPILED`), else the reference. The two differ by
float32 rounding (the order of each sum, documented in the C file):
tests/policy/test_row_forward.py holds the compiled forward to the reference within 1e-4
relative and absolute.

`mean_views` averages blocks of consecutive output rows (a task network's Q-values over the K
views of each observation): compiled wherever the module is built (no CPU requirement), the
same float32 sums in the same order as its reference `numpy_mean_views`, so the same values.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from policy._kernels import load_kernel

Layers = Sequence[tuple[np.ndarray, np.ndarray]]

__all__ = [
    "COMPILED",
    "mean_views",
    "numpy_mean_views",
    "numpy_row_forward",
    "row_forward",
    "vector_widths",
]


# policy/_row_forward.c, built by setup.py where a C compiler exists
_extension: Any = load_kernel("_row_forward")

COMPILED: bool = _extension is not None and bool(_extension.AVAILABLE)


def numpy_row_forward(
    x_XPF: np.ndarray, layers: Layers, start: int, members: int, activation: str
) -> np.ndarray:
    """`row_forward` with numpy: the reference, and the forward where nothing is compiled. One
    member on its own rows runs as 2-D products (BLAS speed; numpy's batched 3-D matmul is not)."""
    h = np.asarray(x_XPF, dtype=np.float32)
    last = len(layers) - 1
    if members == 1 and h.shape[0] == 1:
        h = h[0]
        for k, (w_RIO, b_R1O) in enumerate(layers):
            h = h @ w_RIO[start]
            h += b_R1O[start]
            if k < last:
                _activate(h, activation)
        return h[None]
    for k, (w_RIO, b_R1O) in enumerate(layers):
        h = np.matmul(h, w_RIO[start : start + members])  # x (1, P, F) broadcasts over members
        h += b_R1O[start : start + members]
        if k < last:
            _activate(h, activation)
    return h


def _activate(h: np.ndarray, activation: str) -> None:
    if activation == "relu":
        np.maximum(h, 0.0, out=h)
    else:
        np.tanh(h, out=h)


def vector_widths() -> tuple[int, ...]:
    """The compiled forward's vector widths on this CPU, in floats: (8,) with AVX2, (8, 16)
    with AVX-512F too, () where it is not compiled."""
    if not COMPILED:
        return ()
    return (8, 16) if _extension.WIDEST == 16 else (8,)


def row_forward(
    x_XPF: np.ndarray,
    layers: Layers,
    start: int,
    members: int,
    activation: str,
    *,
    lanes: int = 0,
    numpy: bool = False,
) -> np.ndarray:
    """Members `start` .. `start + members - 1` of the stacked `layers` on their rows (module
    docstring): (members, P, A) float32, compiled when `COMPILED` unless `numpy` asks for the
    reference. `lanes`: the compiled forward's vector width, one of `vector_widths()` (0: the
    widest; for numpy, only 0: numpy has no width to choose)."""
    if numpy or not COMPILED:
        if lanes != 0:
            raise ValueError(
                f"lanes: expected 0 (numpy's forward has no vector width), got {lanes}"
            )
        return numpy_row_forward(x_XPF, layers, start, members, activation)
    x = np.ascontiguousarray(x_XPF, dtype=np.float32)
    result: np.ndarray = _extension.forward(x, layers, start, members, activation, lanes)
    return result


def numpy_mean_views(q_RA: np.ndarray, views: int) -> np.ndarray:
    """`mean_views` with numpy: the reference."""
    rows, n_actions = q_RA.shape
    return (np.add.reduce(q_RA.reshape(rows // views, views, n_actions), axis=1) / views).astype(
        np.float64
    )


def mean_views(q_RA: np.ndarray, views: int) -> np.ndarray:
    """(R / views, A) float64: the float32 mean of each block of `views` consecutive rows of
    the float32 (R, A) `q_RA`; compiled where the module is built."""
    if _extension is None:
        return numpy_mean_views(q_RA, views)
    result: np.ndarray = _extension.mean_views(q_RA, views)
    return result
