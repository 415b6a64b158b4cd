"""A stack of small Q-networks on one observation: the inference engine's single-row forward.

    q_MPA = row_forward(x_XPF, layers, start, members, "relu")

`layers` holds per layer a weight stack (R, in, out) and a bias stack (R, 1, out), float32 (the
`row_weights` of `services.engine.networks.Partition`); member m < `members` is network
`start + m` of the stack and runs on the rows x[m] (X = members) or x[0] (X = 1: every member
on the same P rows). The result is (members, P, A) float32: hidden layers take the activation,
the last one is linear (as `policy.qnet.numpy_stacked_forward`).

Two implementations:
- `policy/_row_forward.c` (built by setup.py; used when `COMPILED`): one loop over the members
  that reads each weight once, AVX-512 or AVX2 with FMA, chosen at import, the GIL released.
  One observation through 35 networks 8-128-128-5 (2.5 MB of weights, not in L2): ~45 µs
  against numpy's ~90 on the dev machine (benchmarks/engine.py), where the product spends most
  of its time waiting on the caches;
- `numpy_row_forward`, the same maths with numpy's stacked matmul (one BLAS call per member and
  layer): the fallback where there is no compiler, no AVX2 or FMA, or COEXIST_PYTHON_FORWARD=1.

The two differ in the last bits (the order of each sum: the C one is documented in its header,
the same on every x86-64 with AVX2); tests/policy/test_row_forward.py bounds the difference.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from policy._extensions import load

Layers = Sequence[tuple[np.ndarray, np.ndarray]]

__all__ = ["COMPILED", "VARIANT", "all_finite", "numpy_row_forward", "row_forward"]


_LOADED = load("_row_forward", "COEXIST_PYTHON_FORWARD")
_EXTENSION = _LOADED if _LOADED is not None and _LOADED.VARIANT != "none" else None
COMPILED = _EXTENSION is not None
VARIANT: str = _EXTENSION.VARIANT if _EXTENSION is not None else "numpy"


def numpy_row_forward(
    x_XPF: np.ndarray, layers: Layers, start: int, members: int, activation: str
) -> np.ndarray:
    """`row_forward` with numpy (the fallback, and the reference of the tests)."""
    h = np.asarray(x_XPF, dtype=np.float32)
    last = len(layers) - 1
    for k, (w_RIO, b_R1O) in enumerate(layers):
        h = np.matmul(h, w_RIO[start : start + members])  # x (1, P, F) broadcasts over members
        h += b_R1O[start : start + members]
        if k < last:
            if activation == "relu":
                np.maximum(h, 0.0, out=h)
            else:
                np.tanh(h, out=h)
    return h


def row_forward(
    x_XPF: np.ndarray, layers: Layers, start: int, members: int, activation: str
) -> np.ndarray:
    """Members `start` .. `start + members - 1` of the stacked `layers` on their rows (module
    docstring): (members, P, A) float32."""
    if _EXTENSION is None:
        return numpy_row_forward(x_XPF, layers, start, members, activation)
    x = np.ascontiguousarray(x_XPF, dtype=np.float32)
    result: np.ndarray = _EXTENSION.forward(x, layers, start, members, activation)
    return result


def all_finite(array: np.ndarray) -> bool:
    """Whether every entry is finite: one compiled scan of a contiguous float32 array (the
    forward's output; ~0.3 µs), else numpy's isfinite."""
    if _EXTENSION is not None and array.dtype == np.float32 and array.flags.c_contiguous:
        return bool(_EXTENSION.all_finite(array))
    return bool(np.isfinite(array).all())
