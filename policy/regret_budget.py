"""AAIL within an episode's regret budget (method `aail_budget`): our addition to §3.3.

Why. The paper's AAIL (eqs. 8-10) bounds nothing the ego pays over an episode: where the task
network is unsure, eq. 9 lets impact networks steer, and on goal pairs nobody tuned on the ego
can park beside its target for good (`reports/paper/discussion.md`). `aail_bounded` is safe by
blending only once the environment says the ego's goal is reached, so it gives up the help on
the way and needs a model of the environment. This blend is safe by accounting instead, with
nothing but the networks and the episode: a constrained-MDP view in which the ego may give up at
most a budget of its own task value over the episode, and spends it only where the partners'
impact networks say the team gains more than the ego pays.

What. Per row, with π_t = Boltzmann(Q_t, α) the task policy, π_C the AAIL policy (eqs. 8-10)
and Q_i the impact Q-vector of partner i (a goal distribution's expectation, §3.2):

    c = Σ_a (π_t(a) - π_C(a)) Q_t(a)                 the ego's task value π_C gives up (B1)
    g = Σ_i Σ_a (π_C(a) - π_t(a)) Q_i(a)             the partners' value π_C raises     (B2)

(eq. 6 defines the impact reward as a change of the partner's soft value, so Q_i and Q_t share
one unit). The episode's budget is a fraction k of the ego's own expected task value where the
episode starts, B = k · |Σ_a π_t(a|s_0) Q_t(s_0, a)|, and S is what the episode spent so far
(S = 0 at s_0). The policy mixes the two,

    π = (1 - β) π_t + β π_C,                                                           (B3)
    β = 0                              where g <= κ · max(c, 0)  (the team gains no more
                                       than κ times what the ego pays: not worth it),
    β = min(1, (B - S) / c)            where c > 0 and g > κ c,
    β = 1                              where c <= 0 and g > 0  (help that costs nothing),

and the episode spends S' = S + β · max(c, 0)                                          (B4).

Mixing is linear in β, so the step costs exactly β c of task value, and S never exceeds B: by
the performance-difference lemma the ego's expected return (as its own network values it) stays
within about B of SL's. Once the budget is spent the ego follows its task policy, which takes
it to its target from wherever it is: no oracle of "goal reached", no simulated dynamics.
κ >= 1 (`gain_ratio`) asks the partners' gain to exceed the ego's cost, so that a blend which
costs the ego more than it brings the others is never taken, however much budget is left.

`budget_rows` is the whole rule for B rows; `initial_budget` gives B for a row at s_0.

Chosen by measurement (`reports/paper/blend_choice.md`, goal pairs drawn with tuning seeds no
report uses, partners of another training seed and 30 %-random ones): larger budgets keep more
of AAIL's help where goals align and cost the team more where they do not; k = 0.01 with
ε = 8α kept the team return at or above SL's on average on non-aligned pairs, with a median own
regret under 2 % and no stranded ego, and about half of the paper AAIL's help on aligned pairs.
The networks' own estimates do not tell the two cases apart well enough for more: the impact
networks claim a gain above the ego's cost (κ = 1, even κ = 2) on most non-aligned steps.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "BUDGET_EPSILON_PER_ALPHA",
    "DEFAULT_BUDGET_FRACTION",
    "DEFAULT_GAIN_RATIO",
    "BudgetStep",
    "budget_rows",
    "initial_budget",
]

DEFAULT_BUDGET_FRACTION = 0.01  # k: measured in reports/paper/blend_choice.md
DEFAULT_GAIN_RATIO = 1.0  # κ: the team must gain more than the ego pays
BUDGET_EPSILON_PER_ALPHA = 8.0  # R1's ε at every step, in units of the task network's α


def initial_budget(
    probs_task_BA: np.ndarray, q_task_BA: np.ndarray, fraction: float | np.ndarray
) -> np.ndarray:
    """B = k · |Σ_a π_t(a) Q_t(a)| per row, (B,): the budget of an episode starting here."""
    value_B = (probs_task_BA * q_task_BA).sum(axis=1)
    return np.asarray(fraction, dtype=np.float64) * np.abs(value_B)


class BudgetStep:
    """What one step of eq. B3-B4 gives for B rows (float64 arrays)."""

    __slots__ = ("beta_B", "cost_B", "gain_B", "probs_BA", "spent_B")

    def __init__(
        self,
        probs_BA: np.ndarray,
        spent_B: np.ndarray,
        beta_B: np.ndarray,
        cost_B: np.ndarray,
        gain_B: np.ndarray,
    ) -> None:
        self.probs_BA = probs_BA  # π of eq. B3
        self.spent_B = spent_B  # S' of eq. B4
        self.beta_B = beta_B  # β of eq. B3, in [0, 1]
        self.cost_B = cost_B  # c of eq. B1
        self.gain_B = gain_B  # g of eq. B2


def budget_rows(
    probs_task_BA: np.ndarray,
    probs_blend_BA: np.ndarray,
    q_task_BA: np.ndarray,
    q_impact_BPA: np.ndarray,
    spent_B: np.ndarray,
    total_B: np.ndarray,
    gain_ratio: float = DEFAULT_GAIN_RATIO,
) -> BudgetStep:
    """Eqs. B1-B4 for B rows: `probs_task_BA` is π_t, `probs_blend_BA` π_C, `q_impact_BPA` one
    impact Q-vector per partner (P may be 0: then g = 0 and π = π_t), `spent_B` S and
    `total_B` B (both >= 0)."""
    delta_BA = probs_blend_BA - probs_task_BA
    cost_B = -(delta_BA * q_task_BA).sum(axis=1)  # eq. B1
    gain_B = np.einsum("ba,bpa->b", delta_BA, q_impact_BPA)  # eq. B2
    paid_B = np.maximum(cost_B, 0.0)
    worth_B = gain_B > gain_ratio * paid_B
    left_B = np.maximum(total_B - spent_B, 0.0)
    affordable_B = np.where(paid_B > 0.0, left_B / np.where(paid_B > 0.0, paid_B, 1.0), 1.0)
    beta_B = np.where(worth_B, np.minimum(affordable_B, 1.0), 0.0)
    probs_BA = probs_task_BA + beta_B[:, None] * delta_BA  # eq. B3
    # the mixture of two distributions is one; renormalise only the rounding
    probs_BA = np.maximum(probs_BA, 0.0)
    probs_BA /= probs_BA.sum(axis=1, keepdims=True)
    spent_new_B = spent_B + beta_B * paid_B  # eq. B4
    return BudgetStep(probs_BA, spent_new_B, beta_B, cost_B, gain_B)
