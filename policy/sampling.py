"""One action per row of a policy: inverse-CDF sampling from given uniforms, and the greedy
action.

    actions_B, greedy_B = sample_rows(probs_BA, u_B)

Row b's action is the first whose cumulative probability exceeds u_b times the row's total
(so an action of probability 0 is never drawn, and a total that rounding moved off 1 changes
nothing), at most A - 1; its greedy action is the first most probable one. `numpy_sample_rows` is the
tests' reference; `policy.blend_kernel.sample_rows` computes the same sums in the same order,
so the two give the same actions (tests/policy/test_sampling.py), in one call instead of
numpy's six. The inference engine draws u from the request's generator, the evaluation from its common
random numbers.
"""

from __future__ import annotations

import numpy as np

from policy import blend_kernel

__all__ = ["numpy_sample_rows", "sample_actions", "sample_rows"]


def numpy_sample_rows(probs_BA: np.ndarray, u_B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`sample_rows` with numpy: the reference."""
    cdf_BA = np.cumsum(probs_BA, axis=1)
    below_BA = cdf_BA <= np.asarray(u_B)[:, None] * cdf_BA[:, -1:]
    actions_B = np.minimum(below_BA.sum(axis=1), probs_BA.shape[1] - 1)
    return actions_B.astype(np.int64), probs_BA.argmax(axis=1).astype(np.int64)


def sample_rows(probs_BA: np.ndarray, u_B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(actions, greedy actions), each (B,) int64, of the (B, A) policy `probs_BA` given one
    uniform in [0, 1) per row (module docstring)."""
    actions_greedy = blend_kernel.sample_rows(
        np.ascontiguousarray(probs_BA, dtype=np.float64), np.ascontiguousarray(u_B, np.float64)
    )
    return actions_greedy[0], actions_greedy[1]


def sample_actions(probs_BA: np.ndarray, u_B: np.ndarray) -> np.ndarray:
    """The sampled actions of `sample_rows` alone."""
    return sample_rows(probs_BA, u_B)[0]
