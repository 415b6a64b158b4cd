"""What a goal belief says, from its log-probabilities (G,): the summaries a session returns and
the goal distribution the act pass blends impact networks by. Part of `policy.belief` (which
re-exports every name here); pure numpy, no I/O.

| function              | what                                                        | result       |
|-----------------------|-------------------------------------------------------------|--------------|
| `top_goals`           | the k most probable goals (ties: goal order)                | list         |
| `belief_entropy`      | entropy in nats                                             | float        |
| `belief_summary`      | both of the above with one exp (a session's every step)     | list, float  |
| `belief_cross_entropy`| -log b(g*) for the true goal g*                             | float        |
| `blend_goal_probs`    | the blend's goal distribution (default: the whole belief)   | dict         |
| `blend_goal_weights`  | the same as goal indices and probabilities                  | lists        |
| `belief_views`        | per row of (P, G): `blend_goal_weights` + `belief_summary`, | `BeliefView`s|
|                       | one exp and one sort for all rows (a session's every step)  |              |
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from policy.belief_compiled import BeliefView, compiled_views

__all__ = [
    "BeliefView",
    "belief_cross_entropy",
    "belief_entropy",
    "belief_summary",
    "belief_views",
    "blend_goal_probs",
    "blend_goal_weights",
    "top_goals",
]


def _is_real(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


def _check_blend(mass: float, max_goals: int | None, below: float = 0.0) -> None:
    if not _is_real(mass) or not 0 < mass <= 1:
        raise ValueError(f"mass: expected a number in (0, 1], got {mass!r}")
    if not _is_real(below) or not 0 <= below <= 1:
        raise ValueError(f"below: expected a number in [0, 1], got {below!r}")
    if max_goals is not None and (
        isinstance(max_goals, bool) or not isinstance(max_goals, int | np.integer) or max_goals < 1
    ):
        raise ValueError(f"max_goals: expected null or an integer >= 1, got {max_goals!r}")


def _belief_vector(log_belief_G: np.ndarray) -> np.ndarray:
    log_b = np.asarray(log_belief_G, dtype=np.float64)
    if log_b.ndim != 1 or log_b.size == 0:
        raise ValueError(f"log_belief_G: expected shape (G,) with G >= 1, got {log_b.shape}")
    return log_b


def top_goals(
    log_belief_G: np.ndarray, goals: Sequence[str], k: int = 3
) -> list[tuple[str, float]]:
    """The k most probable goals with their probabilities, highest first (ties: goal order)."""
    log_b = _belief_vector(log_belief_G)
    if len(goals) != log_b.size:
        raise ValueError(f"goals: expected {log_b.size} goals, got {len(goals)}")
    if k < 1:
        raise ValueError(f"k: expected >= 1, got {k}")
    order = np.argsort(-log_b, kind="stable")[:k]
    probs = np.exp(log_b[order])
    return [(goals[g], float(p)) for g, p in zip(order.tolist(), probs.tolist(), strict=True)]


def belief_entropy(log_belief_G: np.ndarray) -> float:
    """Entropy of the belief in nats (0 when certain, log G when uniform)."""
    log_b = _belief_vector(log_belief_G)
    b = np.exp(log_b)
    terms = np.where(b > 0, b * np.where(b > 0, log_b, 0.0), 0.0)  # 0 log 0 = 0
    return max(0.0, float(-terms.sum()))


def belief_summary(
    log_belief_G: np.ndarray, goals: Sequence[str], k: int = 3
) -> tuple[list[tuple[str, float]], float]:
    """`top_goals(log_belief_G, goals, k)` and `belief_entropy(log_belief_G)` in one pass (one
    exp): the same numbers, for a caller that summarises a belief at every step."""
    log_b = _belief_vector(log_belief_G)
    if len(goals) != log_b.size:
        raise ValueError(f"goals: expected {log_b.size} goals, got {len(goals)}")
    if k < 1:
        raise ValueError(f"k: expected >= 1, got {k}")
    b = np.exp(log_b)
    order = np.argsort(-log_b, kind="stable")[:k].tolist()
    probs = b.tolist()
    positive = b.min() > 0  # the floor's usual case: no 0 log 0 terms to mask
    terms = b * log_b if positive else np.where(b > 0, b * np.where(b > 0, log_b, 0.0), 0.0)
    return [(goals[g], probs[g]) for g in order], max(0.0, float(-terms.sum()))


def belief_cross_entropy(log_belief_G: np.ndarray, true_index: int) -> float:
    """-log b(g*), in nats, for the true goal's index g* (inf when the belief rules it out)."""
    log_b = _belief_vector(log_belief_G)
    if isinstance(true_index, bool) or not 0 <= true_index < log_b.size:
        raise ValueError(f"true_index: expected 0..{log_b.size - 1}, got {true_index!r}")
    return float(-log_b[true_index])


def blend_goal_probs(
    log_belief_G: np.ndarray,
    goals: Sequence[str],
    mass: float = 1.0,
    max_goals: int | None = None,
) -> dict[str, float]:
    """The goal distribution the act pass blends impact networks by (§3.2: the expected impact
    Q under the belief), renormalised to sum to 1, in the order of `goals`.

    Default: the whole belief, every goal of probability > 0 (all G with a floor). The blend is
    then exact, and the goal set, hence the set of impact networks, is the same at every step:
    the engine reuses one stacked group and one row layout. `mass` < 1 or `max_goals` < G keep
    the most probable goals until they cover `mass` (at most `max_goals`); the set changes as the
    belief moves, and the engine serves such changing sets from the stacked group of every
    goal's network (`services.engine.engine`, "Goal distributions"). The order of `goals` (not
    by probability) keeps a request's shape, and the engine's cached plans, fixed while the set
    is."""
    log_b = _belief_vector(log_belief_G)
    if len(goals) != log_b.size:
        raise ValueError(f"goals: expected {log_b.size} goals, got {len(goals)}")
    kept, probs = blend_goal_weights(log_b, mass, max_goals)
    return {goals[g]: p for g, p in zip(kept, probs, strict=True)}


def blend_goal_weights(
    log_belief_G: np.ndarray,
    mass: float = 1.0,
    max_goals: int | None = None,
    below: float = 0.0,
    below_mass: float = 1.0,
) -> tuple[list[int], list[float]]:
    """`blend_goal_probs` as the kept goals' indices (ascending) and their probabilities;
    `below` > 0 also leaves out every goal of probability below it but the most probable (goal
    pruning, `policy.belief_prune`), while the mass left out is at most `below_mass`."""
    log_b = _belief_vector(log_belief_G)
    _check_blend(mass, max_goals, below)
    probs = np.exp(log_b).tolist()
    whole = _whole(mass, max_goals, log_b.size, below)
    order = None if whole else np.argsort(-log_b, kind="stable")
    kept, probs = _blend_kept(probs, order, mass, max_goals, below, below_mass)
    total = math.fsum(probs)
    return kept, [p / total for p in probs]


def _whole(mass: float, max_goals: int | None, n_goals: int, below: float = 0.0) -> bool:
    """Whether the blend keeps every goal of probability > 0 (no ordering needed)."""
    return mass >= 1 and (max_goals is None or max_goals >= n_goals) and below <= 0


def _blend_kept(
    probs: list[float],
    order: np.ndarray | None,
    mass: float,
    max_goals: int | None,
    below: float = 0.0,
    below_mass: float = 1.0,
) -> tuple[list[int], list[float]]:
    """The blend's goals (ascending) and their unnormalised probabilities, from one row's
    probabilities and, unless the blend is `_whole`, its goals by descending probability.
    `below` leaves out the goals under it only while their mass is at most `below_mass`."""
    if order is None:
        kept = [g for g, p in enumerate(probs) if p > 0]
    else:
        kept = _ordered_kept(probs, order, mass, max_goals, below)
        if below > 0 and below_mass < 1:
            left = math.fsum(probs) - math.fsum([probs[g] for g in kept])
            if left > below_mass:  # too much mass under τ: blend as without it
                kept = (
                    [g for g, p in enumerate(probs) if p > 0]
                    if _whole(mass, max_goals, len(probs))
                    else _ordered_kept(probs, order, mass, max_goals, 0.0)
                )
    if not kept:
        raise ValueError("log_belief_G: every goal has probability 0")
    if len(kept) < len(probs):
        probs = [probs[g] for g in kept]
    return kept, probs


def _ordered_kept(
    probs: list[float], order: np.ndarray, mass: float, max_goals: int | None, below: float
) -> list[int]:
    kept: list[int] = []
    covered = 0.0
    for g in order[: None if max_goals is None else int(max_goals)].tolist():
        if probs[g] <= 0 or (kept and probs[g] < below):  # descending: the rest too
            break
        kept.append(g)
        covered += probs[g]
        if covered >= mass * (1 - 1e-12):  # rounding must not add a goal for 1e-16 of mass
            break
    kept.sort()
    return kept


def belief_views(
    log_belief_PG: np.ndarray,
    goals: Sequence[str],
    k: int = 3,
    mass: float = 1.0,
    max_goals: int | None = None,
    below: float = 0.0,
    below_mass: float = 1.0,
) -> list[BeliefView]:
    """Per row p of a (P, G) log-belief: `blend_goal_weights(row, mass, max_goals, below,
    below_mass)` and
    `belief_summary(row, goals, k)`, the same numbers bit for bit, with one exp, one sort and
    one sum for all rows instead of two exps and a sort per row (elementwise operations and
    the last-axis sum give every row what they give it alone; a division of arrays rounds as
    Python's does). Compiled where the whole belief is blended (`policy.belief_compiled`, equal
    within 1e-12)."""
    log_b = np.asarray(log_belief_PG, dtype=np.float64)
    if log_b.ndim != 2 or log_b.shape[1] == 0:
        raise ValueError(f"log_belief_PG: expected shape (P, G) with G >= 1, got {log_b.shape}")
    n_goals = log_b.shape[1]
    if len(goals) != n_goals:
        raise ValueError(f"goals: expected {n_goals} goals, got {len(goals)}")
    if k < 1:
        raise ValueError(f"k: expected >= 1, got {k}")
    _check_blend(mass, max_goals, below)
    if log_b.shape[0] == 0:
        return []
    if _whole(mass, max_goals, n_goals, below):  # compiled where it can
        views = compiled_views(log_b, goals, k)
        if views is not None:
            return views
    return reference_views(log_b, goals, k, mass, max_goals, below, below_mass)


def reference_views(
    log_b: np.ndarray,
    goals: Sequence[str],
    k: int,
    mass: float,
    max_goals: int | None,
    below: float = 0.0,
    below_mass: float = 1.0,
) -> list[BeliefView]:
    """`belief_views` in numpy on checked arguments (a non-empty (P, G) float64 `log_b`): the
    compiled views' reference, and the beliefs they leave (a partial blend, a zero
    probability)."""
    n_goals = log_b.shape[1]
    b = np.exp(log_b)
    order = np.argsort(-log_b, axis=1, kind="stable")
    positive = b.min() > 0  # the floor's usual case: no 0 log 0 terms to mask
    terms = b * log_b if positive else np.where(b > 0, b * np.where(b > 0, log_b, 0.0), 0.0)
    entropies = terms.sum(axis=1).tolist()
    tops = order[:, :k].tolist()
    whole = _whole(mass, max_goals, n_goals, below)
    views = []
    for p, row in enumerate(b.tolist()):
        top = [(goals[g], row[g]) for g in tops[p]]
        if whole and positive:  # every goal kept: `_blend_kept` would copy the row as it is
            kept, probs = list(range(n_goals)), row
        else:
            kept, probs = _blend_kept(
                row, None if whole else order[p], mass, max_goals, below, below_mass
            )
        total = math.fsum(probs)
        views.append(BeliefView(kept, [q / total for q in probs], top, max(0.0, -entropies[p])))
    return views
