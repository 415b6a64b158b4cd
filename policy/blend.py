"""Blending a task Q-vector with one impact Q-vector per partner: SL, NAIL and AAIL (§3.3, §4.2).

Shapes: B states (rows), P partner slots, G partner goals, A actions.

| argument          | shape      | meaning                                                    |
|-------------------|------------|------------------------------------------------------------|
| `q_task_BA`       | (B, A)     | the ego's task network Q_t                                 |
| `q_impact_BPA`    | (B, P, A)  | one impact Q_i per partner slot (P may be 0)               |
| `partner_mask_BP` | (B, P) bool| which slots hold a partner (default: all); masked slots    |
|                   |            | are ignored entirely, even if they hold NaN                |
| `alpha`           | scalar/(B,)| Boltzmann temperature α > 0                                |

Methods (`METHODS`):
- **SL**: the task network alone, Q = Q_t.
- **NAIL** (paper §4.2, "simple averaging"): the plain mean of the *raw* Q-vectors of the task
  network and the active impact networks, Q = (Q_t + Σ_i Q_i) / (1 + P_active).
- **AAIL-bounded** (`aail_bounded`, ours): AAIL's policy with a bound ε on the ego's own
  regret, `regret_bound` (eq. R1 of `policy.regret_bound`): actions within ε of the task's best
  share the task policy's probability on them as AAIL says; every other action keeps its task
  probability. Diagnostics (entropy, weights) are AAIL's. The engine adds what needs the
  environment (R2-R4 of `policy.regret_bound`: blend only once the ego's goal is reached, with a
  flat task Q once it is reached for good, never losing a reached goal that can be kept).
- **AAIL** (eqs. 8-10): π_t = Boltzmann(Q_t, α), π_i = Boltzmann(Q_i, α);
  w_t = 1 - |A|^H(π_t) / |A| (eq. 9); w_i = JSD(π_t ‖ π_i), the Jensen-Shannon distance
  (eq. 10); ŵ_i = w_i / Σ_j w_j, or equal ŵ_i = 1 / P_active when Σ_j w_j = 0 (every impact
  policy equals the task policy: nothing tells them apart, and there is no NaN).
  Normalisation before blending (the paper asks for it without saying how; this is our choice):
  each Q-vector is standardised over actions, z = (Q - mean_A Q) / std_A Q (a vector with std 0,
  or std below 1e-12 of its magnitude, gets z = 0: it expresses no preference). The preferences
  are blended with eq. 8, z_C = w_t z_t + (1 - w_t) Σ_i ŵ_i z_i, and given back a Q scale with
  the same weights, s_C = w_t s_t + (1 - w_t) Σ_i ŵ_i s_i, so Q_C = s_C · z_C. Each network thus
  contributes by its weight, not by the magnitude of its rewards, and the blended Q keeps the
  typical scale of its inputs so that α means the same as for the networks themselves.
  A row with no active partner uses w_t = 1 (there is no compound interaction policy to blend
  in), so Q_C = Q_t - mean_A Q_t and the policy equals SL's.
  `normalise=False` blends the raw Q-vectors instead, Q_C = w_t Q_t + (1 - w_t) Σ_i ŵ_i Q_i
  (eq. 8 as written, the same weights): for environments whose task and impact rewards share one
  scale. Standardising blows a nearly flat impact Q-vector (no real preference) up to unit
  spread, so it can outvote a clear task preference; in the cooking kitchen that froze AAIL
  cooks in no-op loops (reports/cooking/README.md), so that environment declares raw blending
  (`Domain.blend_normalisation`).

`mix_goal_beliefs` turns partner goals given as a probability distribution (paper §3.2, last
paragraph) into one impact Q-vector per partner: the expectation of the per-goal impact Q-vectors
under the goal probabilities. Soft Q is linear in the reward for a fixed policy, so this is the
Q of the expected impact reward; it is our choice (the paper only says the framework "allows to
probabilistically combine policies").

`blend_vectorised`, numpy over the whole batch, is the reference (for the tests);
`blend` and `blend_checked` run `policy.blend_kernel`, the same maths compiled by numba row by
row, where numpy's per-call overhead would otherwise dominate the few numbers of a row. The two
agree within 1e-9 (tests/policy/test_blend_kernel.py). `aail_bounded`'s bound (eq. R1) is
`policy.regret_bound.bound_rows` in the reference and a last step of the same kernel.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from policy import blend_kernel
from policy._validate import (
    PROB_SUM_TOL,
    alpha_array,
    float_array,
    require_actions,
    require_finite,
)
from policy.maths import boltzmann, js_distance, normalized_entropy, task_weight
from policy.regret_bound import bound_rows, check_regret_bound

__all__ = [
    "FLAT_STD_RTOL",
    "METHODS",
    "BlendMethod",
    "BlendResult",
    "blend",
    "blend_checked",
    "blend_vectorised",
    "mix_goal_beliefs",
    "standardise",
]

BlendMethod = Literal["sl", "nail", "aail", "aail_bounded"]
METHODS: tuple[BlendMethod, ...] = ("sl", "nail", "aail", "aail_bounded")
FLAT_STD_RTOL = 1e-12  # a Q-vector whose std is below this fraction of max |Q| is "flat"


@dataclass(frozen=True)
class BlendResult:
    """What a blend produced, per row (float64 arrays)."""

    q_BA: np.ndarray  # blended Q used for the final policy
    probs_BA: np.ndarray  # Boltzmann(q_BA, alpha)
    task_entropy_B: np.ndarray  # normalised entropy of the task policy Boltzmann(q_task, alpha)
    # w_t used: 1 for SL, 1/(1+P_active) for NAIL, eq. 9 for AAIL (1 with no active partner)
    task_weight_B: np.ndarray
    partner_weights_BP: np.ndarray  # ŵ_i = w_i / Σ_j w_j per partner, 0 for masked partners


def standardise(q_BKA: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """z-scores over the action axis and the std, (z (..., A), s (...)); flat vectors get z = 0."""
    # Divide by max |q| first so that the squares in the std cannot overflow for |Q| ~ 1e300.
    magnitude = np.abs(q_BKA).max(axis=-1, keepdims=True)
    unit = q_BKA / np.where(magnitude > 0, magnitude, 1.0)
    std_unit = unit.std(axis=-1, keepdims=True)
    flat = std_unit <= FLAT_STD_RTOL
    z = np.where(
        flat, 0.0, (unit - unit.mean(axis=-1, keepdims=True)) / np.where(flat, 1.0, std_unit)
    )
    return z, np.where(flat, 0.0, std_unit * magnitude)[..., 0]


def _check_blend_inputs(
    q_task_BA: ArrayLike, q_impact_BPA: ArrayLike, partner_mask_BP: ArrayLike | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    q_task = float_array(q_task_BA, "q_task_BA")
    q_impact = float_array(q_impact_BPA, "q_impact_BPA")
    if q_task.ndim != 2:
        raise ValueError(f"q_task_BA: expected shape (B, A), got {q_task.shape}")
    require_actions(q_task, "q_task_BA")
    require_finite(q_task, "q_task_BA")
    n_rows, n_actions = q_task.shape
    if q_impact.ndim != 3 or q_impact.shape[0] != n_rows or q_impact.shape[2] != n_actions:
        raise ValueError(
            f"q_impact_BPA: expected shape (B, P, A) = ({n_rows}, P, {n_actions}) to match "
            f"q_task_BA {q_task.shape}, got {q_impact.shape}"
        )
    if partner_mask_BP is None:
        mask = np.ones(q_impact.shape[:2], dtype=bool)
    else:
        mask = np.asarray(partner_mask_BP)
        if mask.dtype != np.bool_ or mask.shape != q_impact.shape[:2]:
            raise ValueError(
                f"partner_mask_BP: expected a bool array of shape (B, P) = {q_impact.shape[:2]} "
                f"to match q_impact_BPA {q_impact.shape}, got {mask.dtype} {mask.shape}"
            )
    q_impact = np.where(mask[..., None], q_impact, 0.0)  # masked slots never matter
    require_finite(q_impact, "q_impact_BPA (unmasked entries)")
    return q_task, q_impact, mask


def _aail(
    q_task: np.ndarray,
    q_impact: np.ndarray,
    mask: np.ndarray,
    alpha_B1: np.ndarray,
    pi_task: np.ndarray,
    normalise: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Blended Q, task weight and normalised partner weights of eqs. 8-10 (`pi_task` comes
    from the caller, which needs it anyway)."""
    n_active_B = mask.sum(axis=1)
    pi_impact = boltzmann(q_impact, alpha_B1)
    w_task = task_weight(pi_task)  # eq. 9
    w_task = np.where(n_active_B > 0, w_task, 1.0)  # nothing to blend in: the task alone
    w_partner = np.where(mask, js_distance(pi_task[:, None, :], pi_impact), 0.0)  # eq. 10
    total = w_partner.sum(axis=1, keepdims=True)
    equal_share = mask / np.maximum(n_active_B, 1)[:, None]
    w_hat = np.where(total > 0, w_partner / np.where(total > 0, total, 1.0), equal_share)
    w_t = w_task[:, None]
    if not normalise:  # eq. 8 on the raw Q-vectors (masked slots are zero)
        q_raw = w_t * q_task + (1.0 - w_t) * np.einsum("bp,bpa->ba", w_hat, q_impact)
        return q_raw, w_task, w_hat

    z_task, s_task = standardise(q_task)
    z_impact, s_impact = standardise(q_impact)
    # eq. 8 on the standardised preferences, then the same weights on the scales
    z_blend = w_t * z_task + (1.0 - w_t) * np.einsum("bp,bpa->ba", w_hat, z_impact)
    s_blend = w_task * s_task + (1.0 - w_task) * (w_hat * s_impact).sum(axis=1)
    return s_blend[:, None] * z_blend, w_task, w_hat


def blend(
    method: BlendMethod,
    q_task_BA: ArrayLike,
    q_impact_BPA: ArrayLike,
    alpha: ArrayLike,
    partner_mask_BP: ArrayLike | None = None,
    *,
    normalise: bool = True,
    regret_bound: float | ArrayLike | None = None,
) -> BlendResult:
    """Blend the task and impact Q-vectors of each row with `method` ("sl", "nail", "aail",
    "aail_bounded", which needs `regret_bound`: one ε, or one per row, `policy.regret_bound`);
    `normalise=False`: AAIL's eq. 8 on the raw Q-vectors (module docstring)."""
    q_task, q_impact, mask, alpha_B1 = _checked(
        method, q_task_BA, q_impact_BPA, alpha, partner_mask_BP
    )
    epsilon = _epsilon(method, regret_bound, q_task.shape[0])
    return blend_checked(
        method,
        _kernel_array(q_task, np.float64),
        _kernel_array(q_impact, np.float64),
        _kernel_array(mask, np.bool_),
        _kernel_array(alpha_B1[:, 0], np.float64),
        normalise,
        None if epsilon is None else _kernel_array(epsilon, np.float64),
    )


def blend_checked(
    method: BlendMethod,
    q_task_BA: np.ndarray,
    q_impact_BPA: np.ndarray,
    mask_BP: np.ndarray,
    alpha_B: np.ndarray,
    normalise: bool,
    epsilon_B: np.ndarray | None,
) -> BlendResult:
    """`blend` on inputs it would accept, already in its working form: C-contiguous arrays
    (read-only ones too) of finite float64 Q-values (B, A) and (B, P, A), a bool mask (B, P), positive
    temperatures (B,) and, for `aail_bounded` only, ε >= 0 per row (B,) (another layout or
    dtype raises TypeError). For a caller that checked them (the
    inference engine validates each request once), except for the Q-values' finiteness: a NaN
    or infinite Q-value of an unmasked slot raises `FloatingPointError`, found in the same pass
    over the inputs."""
    base: BlendMethod = "aail" if method == "aail_bounded" else method
    (n_rows, n_actions), n_slots = q_task_BA.shape, q_impact_BPA.shape[1]
    result = BlendResult(
        np.empty((n_rows, n_actions)),
        np.empty((n_rows, n_actions)),
        np.empty(n_rows),
        np.empty(n_rows),
        np.empty((n_rows, n_slots)),
    )
    blend_kernel.blend_rows(
        _METHOD_CODES[base],
        q_task_BA,
        q_impact_BPA,
        alpha_B,
        mask_BP,
        normalise,
        _NO_BOUND if epsilon_B is None else epsilon_B,
        epsilon_B is not None,
        result.q_BA,
        result.probs_BA,
        result.task_entropy_B,
        result.task_weight_B,
        result.partner_weights_BP,
    )
    return result


def _kernel_array(array: np.ndarray, dtype: type) -> np.ndarray:
    """`array` as the kernel takes it, C-contiguous (the array itself where it is one already;
    a copy of a broadcast α or of a strided view)."""
    return np.ascontiguousarray(array, dtype=dtype)


_METHOD_CODES = {"sl": blend_kernel.SL, "nail": blend_kernel.NAIL, "aail": blend_kernel.AAIL}
_NO_BOUND = np.zeros(0)


def _epsilon(
    method: BlendMethod, regret_bound: float | ArrayLike | None, n_rows: int
) -> np.ndarray | None:
    """ε per row, (B,), for `aail_bounded` (required there), None for the other methods
    (refused there)."""
    if method != "aail_bounded":
        if regret_bound is not None:
            raise ValueError(f"regret_bound: applies to method aail_bounded only, not {method!r}")
        return None
    if regret_bound is None:
        raise ValueError("regret_bound: required for method aail_bounded")
    if np.ndim(regret_bound) == 0:
        return np.full(n_rows, check_regret_bound(regret_bound))  # type: ignore[arg-type]
    values = np.asarray(regret_bound)
    if values.shape != (n_rows,):
        raise ValueError(
            f"regret_bound: expected one number or {n_rows} (one per row), got shape {values.shape}"
        )
    return np.array([check_regret_bound(v) for v in values.tolist()])


def _bounded(
    result: BlendResult, q_task: np.ndarray, alpha_B1: np.ndarray, epsilon: np.ndarray
) -> BlendResult:
    """AAIL's result with its policy bounded (eq. R1, `policy.regret_bound`)."""
    probs_task = boltzmann(q_task, alpha_B1[:, 0])
    probs = bound_rows(np.asarray(result.probs_BA), q_task, probs_task, epsilon)
    return replace(result, probs_BA=probs)


def blend_vectorised(
    method: BlendMethod,
    q_task_BA: ArrayLike,
    q_impact_BPA: ArrayLike,
    alpha: ArrayLike,
    partner_mask_BP: ArrayLike | None = None,
    *,
    normalise: bool = True,
    regret_bound: float | ArrayLike | None = None,
) -> BlendResult:
    """`blend` on the vectorised numpy path whatever the size (the reference for the fast path)."""
    q_task, q_impact, mask, alpha_B1 = _checked(
        method, q_task_BA, q_impact_BPA, alpha, partner_mask_BP
    )
    epsilon = _epsilon(method, regret_bound, q_task.shape[0])
    base: BlendMethod = "aail" if method == "aail_bounded" else method
    result = _vectorised(base, q_task, q_impact, mask, alpha_B1, normalise)
    return result if epsilon is None else _bounded(result, q_task, alpha_B1, epsilon)


def _checked(
    method: BlendMethod,
    q_task_BA: ArrayLike,
    q_impact_BPA: ArrayLike,
    alpha: ArrayLike,
    partner_mask_BP: ArrayLike | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    if method not in METHODS:
        raise ValueError(f"method: unknown blending method {method!r} (expected one of {METHODS})")
    q_task, q_impact, mask = _check_blend_inputs(q_task_BA, q_impact_BPA, partner_mask_BP)
    return q_task, q_impact, mask, alpha_array(alpha, q_task.shape[:1])


def _vectorised(
    method: BlendMethod,
    q_task: np.ndarray,
    q_impact: np.ndarray,
    mask: np.ndarray,
    alpha_B1: np.ndarray,
    normalise: bool = True,
) -> BlendResult:
    n_active_B = mask.sum(axis=1)
    pi_task = boltzmann(q_task, alpha_B1[:, 0])
    task_entropy = normalized_entropy(pi_task)

    if method == "sl":
        q = q_task
        w_task = np.ones(q_task.shape[0])
        w_partner = np.zeros(mask.shape)
    elif method == "nail":
        q = (q_task + q_impact.sum(axis=1)) / (1.0 + n_active_B)[:, None]  # masked slots are 0
        w_task = 1.0 / (1.0 + n_active_B)
        w_partner = mask / np.maximum(n_active_B, 1)[:, None]
    else:
        q, w_task, w_partner = _aail(q_task, q_impact, mask, alpha_B1, pi_task, normalise)

    return BlendResult(
        q_BA=q,
        probs_BA=boltzmann(q, alpha_B1[:, 0]),
        task_entropy_B=task_entropy,
        task_weight_B=w_task,
        partner_weights_BP=w_partner,
    )


def mix_goal_beliefs(
    q_BPGA: ArrayLike, goal_probs_BPG: ArrayLike, *, partner_mask_BP: ArrayLike | None = None
) -> np.ndarray:
    """Expected impact Q per partner under its goal distribution, shape (B, P, A).

    Rows masked out by `partner_mask_BP` (bool (B, P)) are not checked and come back as 0.
    """
    q = float_array(q_BPGA, "q_BPGA")
    probs = float_array(goal_probs_BPG, "goal_probs_BPG")
    if q.ndim != 4:
        raise ValueError(f"q_BPGA: expected shape (B, P, G, A), got {q.shape}")
    require_actions(q, "q_BPGA")
    if probs.shape != q.shape[:3]:
        raise ValueError(
            f"goal_probs_BPG: expected shape (B, P, G) = {q.shape[:3]} to match q_BPGA "
            f"{q.shape}, got {probs.shape}"
        )
    if partner_mask_BP is None:
        mask = np.ones(q.shape[:2], dtype=bool)
    else:
        mask = np.asarray(partner_mask_BP)
        if mask.dtype != np.bool_ or mask.shape != q.shape[:2]:
            raise ValueError(
                f"partner_mask_BP: expected a bool array of shape (B, P) = {q.shape[:2]}, "
                f"got {mask.dtype} {mask.shape}"
            )
    q = np.where(mask[..., None, None], q, 0.0)
    probs = np.where(mask[..., None], probs, 0.0)
    require_finite(q, "q_BPGA")
    require_finite(probs, "goal_probs_BPG")
    if (probs < 0).any():
        raise ValueError("goal_probs_BPG: goal probabilities must be non-negative")
    off = np.abs(probs.sum(axis=-1) - 1.0)[mask]
    if off.size and (off > PROB_SUM_TOL).any():
        raise ValueError(
            f"goal_probs_BPG: goal probabilities must sum to 1 over G (tolerance "
            f"{PROB_SUM_TOL:g}); worst partner is off by {float(off.max()):.3g}"
        )
    return np.einsum("bpg,bpga->bpa", probs, q)
