"""AAIL with a bound on the ego's own regret (method `aail_bounded`): our addition to §3.3.

Why. Eq. 9 lowers the task weight w_t wherever the task policy is unsure, and the particle
world's blend standardises every Q-vector before eq. 8. Just outside its target area the ego's
task network is often unsure in that sense (one step more or less costs little), and an impact
network whose Q-vector is nearly flat there is blown up to the same unit spread as the task's:
the blend then prefers resting or turning back, the state barely changes, and the ego parks
beside its target for the rest of the episode (`reports/paper/discussion.md`). The paper's
lemmas bound the regret of a blended *Q-function*; nothing bounds what the blended *policy*
costs the ego step after step.

What. Let π_t = Boltzmann(Q_t, α) be the task policy, π_C the AAIL policy (eqs. 8-10) and
ε >= 0 the regret bound. The actions within ε of the task's best,

    S_ε = {a : Q_t(a) >= max_b Q_t(b) - ε},

share the task policy's probability on them as the blend says; every other action keeps exactly
its task probability:

    π_B(a) = π_t(S_ε) · π_C(a) / π_C(S_ε)   for a in S_ε,                       (R1)
    π_B(a) = π_t(a)                         otherwise.

Then the one-step regret against the task policy is bounded,

    Σ_a π_t(a) Q_t(a) - Σ_a π_B(a) Q_t(a) = π_t(S_ε) (E_{π_t|S_ε} Q_t - E_{π_C|S_ε} Q_t) <= ε,

so following π_B instead of π_t costs the ego at most ε / (1 - γ) of its discounted value
(performance-difference lemma). Where the task is indifferent (inside its target area, every
action within ε) π_B is the AAIL policy and the ego helps freely; where one action is clearly
better (on its way to the target) π_B is the task policy, sampling noise included, so the ego
moves and explores exactly as SL does. With ε = 0 (and no ties) π_B = π_t; as ε grows π_B
tends to π_C. When π_C puts no probability on S_ε at all (underflow), π_B = π_t.

The progress guard (R2). ε is not a constant: where the environment can tell from the
observation that the ego's own goal is not reached yet (`envs.base.Domain.goal_reached`; the
particle world: the ego is outside its target area), ε = 0 and π_B is the task policy itself.
Why: a per-step bound does not stop the ego from drifting to where the task network's own
preferences differ by less than ε and parking there, just outside its target, for the rest of
the episode; measured, such task networks exist (`reports/paper/blend_choice.md`). With the
guard, helping never delays the ego's own task: it blends only once its task is done, as the
paper's kitchen cook hands the carrot over after cooking its own dish (the kitchen tells it by
the cook's `served` feature). Where an environment's observations cannot tell, ε applies
everywhere.

A reached goal (R3). Where the ego's goal is reached for good (`Domain.goal_is_final`: a served
dish stays served, and no later step costs the cook anything), no action changes the ego's own
return, so its exact task Q is the same for every action. The same holds where the goal is
reached and can be kept (`Domain.goal_kept` holds some action K, R4 below): the particle ego's
own reward is 0 anywhere inside its target, so under the exact task Q every action of K is
worth the same to it. A trained network is only close to that: its residual preferences there
(a few α: where inside the target to rest, which way the kitchen cook faces) are approximation
error, yet eq. 9 reads them as confidence, keeps the impact networks out, and R1 lets them
share only the actions within ε of that spurious best. There the engine blends with the row's
task Q replaced by its mean over the actions (`services.engine.engine.aail_bounded_guard`): π_t
is uniform, w_t = 0 (eq. 9), every action lies in S_ε, and π_B is the impact networks' blend,
restricted to K by R4. The ego's regret is 0 there (as long as it stays in K, which R4 sees to),
so the bound still holds. Measured on tuning draws (`reports/paper/blend_choice.md`): where the
partner's influence area lies inside the ego's target, the ego then helps more than the paper's
AAIL does (the paper's AAIL keeps weighing its task network's residual preferences inside the
target), never at the cost of its own target. With ε = 0 nothing is flattened: an explicit
`regret_bound` of 0 is the task policy itself.

Keeping the goal (R4). Where the goal is reached but can be lost (the particle world's target
area) and ε > 0, let K be the actions after which the ego is still inside and can stay there by
resting (`Domain.goal_kept`). If K holds some but not all actions,

    π_K(a) = π_B(a) / π_B(K)   for a in K,   0 otherwise,                        (R4)

else π_K = π_B (also when π_B(K) = 0). Why: the ego's own reward is 0 inside its target and
negative outside, so under the exact task Q no action of K is worse than one outside it, and R4
moves probability only towards better actions; the bound of R1 still holds. And it matters
beyond the ego's own reward: an episode ends only when every agent is inside its target at the
same step, so an ego that R1 lets drift to its target's edge and step out just as the last
partner arrives keeps everybody paying for several more steps (measured in five-agent scenes:
`reports/paper/blend_choice.md`). R4 applies where the blend does (ε > 0 on the row), so an
explicit ε = 0 still gives the task policy itself.

The engine's default ε is `DEFAULT_EPSILON_PER_ALPHA` × the task network's temperature α: an
action keeps the blend's say when the task policy rates it at least e^-2 ≈ 0.14 as likely as its
best. ε only acts once the ego's goal is reached (R2); where R3 flattens the task Q (a goal that
is final, or one that some action keeps) every action is within ε, so ε decides only on reached
rows that no action keeps, and in environments that cannot say which actions keep the goal. Chosen by measurement on goal sets and
pairs drawn with seeds the report does not use (`reports/paper/blend_choice.md`): before R4,
ε = α let the ego step out of its target in five-agent scenes and α/2 was kept; with R4, 2α
helps more than α/2 or α in five-agent scenes and on aligned pairs at no cost to the ego's own
return, and 4α gains little more. `bound_rows` computes R1 for B rows in numpy: the tests'
reference (`policy.blend_kernel` applies R1 as its last step).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "DEFAULT_EPSILON_PER_ALPHA",
    "MONITOR_KEEP_LOGIT",
    "bound_rows",
    "check_regret_bound",
    "keep_goal_rows",
]

DEFAULT_EPSILON_PER_ALPHA = 2.0
# A goal monitor (`trainer.monitor`) calls an action keeping where it gives it a probability of
# at least 0.9 (logit log 9): a false keep can let the blend pull the ego out of its target, a
# miss only costs help; chosen on tuning draws (`reports/paper/blend_choice.md`, "The goal
# monitors' threshold").
MONITOR_KEEP_LOGIT = math.log(9.0)


def check_regret_bound(value: float) -> float:
    """`value` as a float if it is a finite ε >= 0; ValueError naming `regret_bound` otherwise."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"regret_bound: expected a number >= 0, got {value!r}")
    epsilon = float(value)
    if not math.isfinite(epsilon) or epsilon < 0.0:
        raise ValueError(f"regret_bound: expected a finite number >= 0, got {value!r}")
    return epsilon


def bound_rows(
    probs_blend_BA: np.ndarray,
    q_task_BA: np.ndarray,
    probs_task_BA: np.ndarray,
    epsilon: float | np.ndarray,
) -> np.ndarray:
    """π_B of eq. R1 for each row, (B, A): `probs_blend_BA` is π_C, `probs_task_BA` π_t;
    `epsilon` one ε, or one per row (B,) (the progress guard R2 sets it to 0 per row)."""
    epsilon_B1 = np.reshape(np.asarray(epsilon, dtype=np.float64), (-1, 1))
    inside_BA = q_task_BA >= q_task_BA.max(axis=1, keepdims=True) - epsilon_B1
    task_mass_B1 = np.where(inside_BA, probs_task_BA, 0.0).sum(axis=1, keepdims=True)
    blend_inside_BA = np.where(inside_BA, probs_blend_BA, 0.0)
    blend_mass_B1 = blend_inside_BA.sum(axis=1, keepdims=True)
    usable_B1 = blend_mass_B1 > 0.0
    share_BA = blend_inside_BA / np.where(usable_B1, blend_mass_B1, 1.0)
    bounded_BA = np.where(inside_BA, task_mass_B1 * share_BA, probs_task_BA)
    return np.where(usable_B1, bounded_BA, probs_task_BA)


def keep_goal_rows(probs_BA: np.ndarray, kept_BA: np.ndarray) -> np.ndarray:
    """π_K of eq. R4 for each row, (B, A): `probs_BA` is π_B, `kept_BA` the actions that keep the
    goal (a row of all True, or all False, is left as it is; so is a row with π_B(K) = 0)."""
    kept_mass_B1 = np.where(kept_BA, probs_BA, 0.0).sum(axis=1, keepdims=True)
    partial_B1 = kept_BA.any(axis=1, keepdims=True) & ~kept_BA.all(axis=1, keepdims=True)
    usable_B1 = partial_B1 & (kept_mass_B1 > 0.0)
    kept_BA_probs = np.where(kept_BA, probs_BA, 0.0) / np.where(usable_B1, kept_mass_B1, 1.0)
    return np.where(usable_B1, kept_BA_probs, probs_BA)
