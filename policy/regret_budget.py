"""AAIL within an episode's regret budget (method `aail_budget`): our addition to §3.3.

Why. The paper's AAIL (eqs. 8-10) bounds nothing the ego pays over an episode: where the task
network is unsure, eq. 9 lets impact networks steer, and on goal pairs nobody tuned on the ego
can park beside its target for good (`reports/paper/discussion.md`). `aail_bounded` is safe by
blending only once the environment says the ego's goal is reached, so it needs a model of the
environment. This blend is safe by accounting instead, with nothing but the ego's task network
and the episode: the ego follows AAIL while what that has cost its own task stays within a
budget, and its task policy for good once it does not.

What. Per row, with π_t = Boltzmann(Q_t, α) the task policy, π_C the AAIL policy (eqs. 8-10)
and V(s) = α log Σ_a exp(Q_t(s, a) / α) the ego's soft task value (eq. 3):

    c_t = Σ_a (π_t(a) - π_C(a)) Q_t(s_t, a)     the task value π_C gives up at step t   (B1)

An episode carries S (spent, S_0 = 0), its budget B and the value V_{t-1} of its last step.
While S < B, step t first charges what the ego's value really lost since the last step,

    S⁺ = max(0, S + V_{t-1} - V(s_t)),                                                   (B2)

then acts

    π = π_C,  S' = max(0, S⁺ + c_t)     where S⁺ < B,                                    (B3)
    π = π_t,  S' = S⁺                   otherwise;

and once S >= B the ego follows π_t for the rest of the episode (S' = S)               (B4).

B2-B3 are Page's CUSUM of the charges (V_{t-1} - V_t + c_{t-1}): S grows while the charges keep
a positive mean and falls back towards 0 (never below) while they do not. B2 alone is the
drawdown of the ego's value below its best so far (the floor makes the sum telescope): being
pulled out of its target, or away from it, shows as a drop of V. B1 is what the ego's own
network expects the blend to cost before it acts: it sees a blend that holds the ego where its
value does not move but it should, beside its target (the parking of
`reports/paper/blend_choice.md`). Where helping costs the ego nothing, inside a target that
holds the partner's influence area, V only wobbles (the partners move, the networks
approximate) and c is about 0 (the task Q is flat): S stays near 0 and the ego helps for as long
as the episode lasts. Once S reaches B the ego follows its task policy, which takes it to its
target from wherever it is: no oracle of "goal reached", no simulated dynamics, and the one step
that crosses B is the most the ego gives up beyond it.

B is a number of the task network's own units (its soft values), `DEFAULT_BUDGET_PER_ALPHA` ×
its training temperature α by default. `budget_rows` is the whole rule for B rows.

Chosen by measurement (`reports/paper/blend_choice.md`, goal pairs drawn with tuning seeds no
report uses, every partner type of `evaluation.partner_types`): charging the realised drop of V
as well as the expected cost kept about three quarters of the paper AAIL's help on aligned pairs
(the earlier rule, the expected cost alone charged against k·|V(s_0)|, kept about two fifths)
without stranding the ego more often than SL does; what it cannot do is help a partner for long
inside its target where the partner's own value never improves (an idle partner), where the
value wobbles add up.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEFAULT_BUDGET_PER_ALPHA", "BudgetStep", "budget_rows", "initial_budget"]

DEFAULT_BUDGET_PER_ALPHA = 8.0  # B in units of the task network's α: reports/paper/blend_choice.md


def initial_budget(budget: float, n_rows: int) -> np.ndarray:
    """B for `n_rows` rows at an episode's first step, (B,) float64."""
    return np.full(n_rows, float(budget))


class BudgetStep:
    """What one step of eqs. B1-B4 gives for B rows (float64 arrays)."""

    __slots__ = ("blend_B", "cost_B", "probs_BA", "spent_B")

    def __init__(
        self, probs_BA: np.ndarray, spent_B: np.ndarray, blend_B: np.ndarray, cost_B: np.ndarray
    ) -> None:
        self.probs_BA = probs_BA  # π of eq. B3
        self.spent_B = spent_B  # S' of eqs. B3-B4
        self.blend_B = blend_B  # bool: whether the row followed π_C
        self.cost_B = cost_B  # c of eq. B1


def budget_rows(
    probs_task_BA: np.ndarray,
    probs_blend_BA: np.ndarray,
    q_task_BA: np.ndarray,
    value_B: np.ndarray,
    spent_B: np.ndarray,
    total_B: np.ndarray,
    last_value_B: np.ndarray,
) -> BudgetStep:
    """Eqs. B1-B4 for B rows: `probs_task_BA` is π_t, `probs_blend_BA` π_C, `value_B` V(s_t),
    `spent_B` S (>= 0), `total_B` B and `last_value_B` V_{t-1} (V(s_t) itself at an episode's
    first step: nothing lost yet)."""
    cost_B = ((probs_task_BA - probs_blend_BA) * q_task_BA).sum(axis=1)  # eq. B1
    live_B = spent_B < total_B  # eq. B4: a spent budget stays spent
    charged_B = np.maximum(spent_B + last_value_B - value_B, 0.0)  # eq. B2
    blend_B = live_B & (charged_B < total_B)
    probs_BA = np.where(blend_B[:, None], probs_blend_BA, probs_task_BA)  # eq. B3
    spent_new_B = np.where(
        live_B, np.where(blend_B, np.maximum(charged_B + cost_B, 0.0), charged_B), spent_B
    )
    return BudgetStep(probs_BA, spent_new_B, blend_B, cost_B)
