"""Online goal inference: a Bayesian belief over a partner's goal from its observed actions.

The paper lets a partner's goal be a probability distribution (§3.2, last paragraph) but does not
say where it comes from. Here it is the posterior of the partner's actions under its *task*
policies, each a Boltzmann policy of its task network (eq. 2):

    P(g | a_1..a_T) ∝ P(g) Π_t π_g(a_t | s_t),    π_g(a | s) = softmax(Q_g(s, ·) / α_g)[a]

kept in log space, with two changes a deployment needs (`BeliefConfig`):

- forgetting λ in (0, 1]: before each update the old log-belief is scaled by λ and the log-prior
  by 1 - λ, a geometric pull back toward the prior, so a partner who changes its mind is followed
  (the evidence of k steps ago weighs λ^k). λ = 1 is the plain Bayes product.
- floor ε in [0, 1/G): after each update the belief is mixed with the uniform distribution,
  b'' = (1 - Gε) b' + ε, so every goal keeps probability >= ε and can come back when the
  evidence turns (no goal is ruled out for good). The forgetting target is the prior with the
  same floor, so a zero in the prior does not pin a goal at ε forever either.

| function                     | what                                             | shape        |
|------------------------------|--------------------------------------------------|--------------|
| `prior_log_probs`            | uniform, a given prior, or an announced goal     | (G,)         |
| `initial_log_belief`         | the prior with the floor applied                 | like input   |
| `boltzmann_log_likelihoods`  | log π_g(a_p | s_p) from Q-values (eq. 2)         | (P, G)       |
| `update_log_belief`          | one step: forget, multiply, normalise, floor     | (P, G)/(G,)  |
| `evidence_rows`              | which likelihood rows count as evidence          | (P,)/()      |
| `top_goals`                  | the k most probable goals                        | list         |
| `belief_entropy`             | entropy in nats                                  | float        |
| `belief_cross_entropy`       | -log b(g*) for the true goal g*                  | float        |
| `blend_goal_probs`           | the goals covering `mass` of the belief (blend)  | dict         |

Stability: the likelihood subtracts max Q before dividing by α (so Q ~ 1e4 with α ~ 1e-6 gives
large finite negatives, never NaN) and normalisation uses logsumexp. A likelihood row that holds
NaN or +inf, or no finite entry at all, is no evidence: that row of the belief is left unchanged,
and so is a row whose update would leave no goal possible (only reachable with ε = 0).
Pure numpy, float64; no I/O (imports nothing from the services).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from policy._validate import PROB_SUM_TOL

__all__ = [
    "BeliefConfig",
    "belief_cross_entropy",
    "belief_entropy",
    "blend_goal_probs",
    "boltzmann_log_likelihoods",
    "evidence_rows",
    "initial_log_belief",
    "prior_log_probs",
    "top_goals",
    "update_log_belief",
]


def _is_real(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


@dataclass(frozen=True)
class BeliefConfig:
    """How the belief is updated (module docstring); `validate` checks it for G goals."""

    forgetting: float = 0.95  # λ in (0, 1]: 1 = never forget
    floor: float = 1e-3  # ε in [0, 1/G): every goal keeps probability >= ε
    temperature: float | None = None  # α of the likelihood; None: each task net's training α

    def validate(self, n_goals: int) -> None:
        """ValueError naming the field (`belief.forgetting`, ...) when a value is out of range."""
        lam, eps, alpha = self.forgetting, self.floor, self.temperature
        if not _is_real(lam) or not 0 < lam <= 1:
            raise ValueError(f"belief.forgetting: expected a number in (0, 1], got {lam!r}")
        if n_goals < 1:
            raise ValueError(f"n_goals: expected >= 1, got {n_goals}")
        if not _is_real(eps) or not 0 <= eps < 1 / n_goals:
            raise ValueError(
                f"belief.floor: expected a number in [0, 1/G) = [0, {1 / n_goals:.6g}) "
                f"for G = {n_goals} goals, got {eps!r}"
            )
        if alpha is not None and (not _is_real(alpha) or not 0 < alpha < math.inf):
            raise ValueError(
                f"belief.temperature: expected null or a finite number > 0, got {alpha!r}"
            )


def prior_log_probs(
    goals: Sequence[str],
    prior: Mapping[str, float] | None = None,
    announced: str | None = None,
    announced_weight: float = 0.9,
) -> np.ndarray:
    """Log prior over `goals`, shape (G,): uniform by default; `prior` maps goal -> probability
    (goals left out get 0; sums to 1 within 1e-6); `announced` puts `announced_weight` on that goal
    and spreads the rest by `prior` (uniformly when None) over the other goals: the partner said
    it but may not mean it. Zeros give -inf; the floor comes in `initial_log_belief`."""
    n_goals = len(goals)
    if n_goals == 0:
        raise ValueError("goals: expected at least one goal")
    index = {goal: g for g, goal in enumerate(goals)}
    if prior is None:
        probs = np.full(n_goals, 1.0 / n_goals)
    else:
        if not isinstance(prior, Mapping) or not prior:
            raise ValueError("prior: expected a non-empty mapping of goal to probability")
        probs = np.zeros(n_goals)
        for goal, p in prior.items():
            if goal not in index:
                raise ValueError(f"prior[{goal}]: unknown goal {goal!r}")
            if not _is_real(p) or not 0 <= p < math.inf:
                raise ValueError(f"prior[{goal}]: expected a finite probability >= 0, got {p!r}")
            probs[index[goal]] = float(p)
        total = math.fsum(probs.tolist())
        if abs(total - 1.0) > PROB_SUM_TOL:
            raise ValueError(
                f"prior: probabilities sum to {total:.9g}, expected 1 (±{PROB_SUM_TOL:g})"
            )
        probs /= total
    if announced is not None:
        if announced not in index:
            raise ValueError(f"announced: unknown goal {announced!r}")
        w = announced_weight
        if not _is_real(w) or not 0 < w <= 1:
            raise ValueError(f"announced_weight: expected a number in (0, 1], got {w!r}")
        rest = probs.copy()
        rest[index[announced]] = 0.0
        rest_total = rest.sum()
        if n_goals == 1:
            probs = np.ones(1)
        elif rest_total > 0:
            probs = (1.0 - w) * rest / rest_total
        else:  # the prior names only the announced goal: spread the doubt uniformly
            probs = np.full(n_goals, (1.0 - w) / (n_goals - 1))
        probs[index[announced]] = w if n_goals > 1 else 1.0
    with np.errstate(divide="ignore"):  # log 0 = -inf is meant
        return np.log(probs)


def _logsumexp(x: np.ndarray) -> np.ndarray:
    """log Σ exp(x) over the last axis, keeping it; rows of -inf give -inf (no warning)."""
    top = x.max(axis=-1, keepdims=True)
    safe = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return safe + np.log(np.exp(x - safe).sum(axis=-1, keepdims=True))


def _apply_floor(log_b: np.ndarray, floor: float, n_goals: int) -> np.ndarray:
    """log((1 - Gε) b + ε) of a normalised log-belief (the result is normalised too)."""
    if floor == 0:
        return log_b
    return np.logaddexp(math.log1p(-n_goals * floor) + log_b, math.log(floor))


def _log_array(x: object, name: str) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected an array of real numbers") from None
    if arr.ndim not in (1, 2) or arr.shape[-1] == 0:
        raise ValueError(f"{name}: expected shape (G,) or (P, G) with G >= 1, got {arr.shape}")
    return arr


def initial_log_belief(log_prior_G: np.ndarray, config: BeliefConfig) -> np.ndarray:
    """The prior, normalised, with the floor applied; shape as given ((G,) or (P, G))."""
    log_prior = _log_array(log_prior_G, "log_prior_G")
    config.validate(log_prior.shape[-1])
    if np.isnan(log_prior).any() or (log_prior == np.inf).any():
        raise ValueError("log_prior_G: expected log-probabilities (no NaN or +inf)")
    norm = _logsumexp(log_prior)
    if not np.isfinite(norm).all():
        raise ValueError("log_prior_G: every goal has probability 0")
    return _apply_floor(log_prior - norm, config.floor, log_prior.shape[-1])


def boltzmann_log_likelihoods(
    q_PGA: np.ndarray,
    actions_P: np.ndarray,
    alpha_G: np.ndarray | float,
    *,
    validate: bool = True,
) -> np.ndarray:
    """log π_g(a_p | s_p) = log softmax(Q_g(s_p) / α_g)[a_p] (eq. 2), shape (P, G).

    `q_PGA` (P, G, A): goal g's task Q-values on partner p's view; `actions_P` (P,) ints in
    0..A-1; `alpha_G` (G,) or a scalar, positive and finite. Non-finite Q-values give a
    non-finite entry, which `update_log_belief` treats as no evidence for that row.
    `validate=False` skips the argument checks (~6 µs) for a caller that made them already."""
    q = np.asarray(q_PGA, dtype=np.float64)
    actions = np.asarray(actions_P)
    alpha = np.asarray(alpha_G, dtype=np.float64)
    if validate:
        alpha = _check_likelihood_args(q, actions, alpha)
    elif alpha.ndim == 1:
        alpha = alpha[:, None]
    with np.errstate(over="ignore", invalid="ignore"):  # see the docstring: NaN is handled later
        z = q - q.max(axis=2, keepdims=True)
        z /= alpha  # <= 0, the arg-max exactly 0 (a tiny α gives -inf, never NaN)
        log_norm = np.log(np.exp(z).sum(axis=2))  # >= log 1 = 0: the arg-max term is exp(0)
    return z[np.arange(q.shape[0]), :, actions] - log_norm  # (P, G): advanced indices first


def _check_likelihood_args(q: np.ndarray, actions: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """The checks of `boltzmann_log_likelihoods`; α shaped to divide (P, G, A) by goal."""
    if q.ndim != 3 or q.shape[2] == 0:
        raise ValueError(f"q_PGA: expected shape (P, G, A) with A >= 1, got {q.shape}")
    n_partners, n_goals, n_actions = q.shape
    if actions.shape != (n_partners,) or (n_partners and actions.dtype.kind not in "iu"):
        raise ValueError(
            f"actions_P: expected {n_partners} integer action(s), got {actions.dtype} "
            f"{actions.shape}"
        )
    if n_partners and (actions.min() < 0 or actions.max() >= n_actions):
        raise ValueError(f"actions_P: expected actions in 0..{n_actions - 1}, got {actions}")
    if alpha.ndim == 0:
        alpha = np.full(n_goals, float(alpha))
    if alpha.shape != (n_goals,) or not (np.isfinite(alpha).all() and (alpha > 0).all()):
        raise ValueError(f"alpha_G: expected {n_goals} finite temperature(s) > 0, got {alpha}")
    return alpha[:, None]


def evidence_rows(log_lik_PG: np.ndarray) -> np.ndarray:
    """Which rows count as evidence: no NaN, no +inf and at least one finite entry."""
    lik = np.asarray(log_lik_PG, dtype=np.float64)
    return (
        ~np.isnan(lik).any(axis=-1) & ~(lik == np.inf).any(axis=-1) & np.isfinite(lik).any(axis=-1)
    )


def update_log_belief(
    log_belief_PG: np.ndarray,
    log_lik_PG: np.ndarray,
    log_prior_PG: np.ndarray,
    config: BeliefConfig,
) -> np.ndarray:
    """One observed action per row: log b' = λ log b + (1 - λ) log prior_ε + log lik, normalised,
    then floored, b'' = (1 - Gε) b' + ε. Shapes (P, G) or (G,); the prior may be (G,) for all
    rows. A new array; rows without evidence (`evidence_rows`) are returned unchanged."""
    log_b = _log_array(log_belief_PG, "log_belief_PG")
    lik = _log_array(log_lik_PG, "log_lik_PG")
    log_prior = _log_array(log_prior_PG, "log_prior_PG")
    if lik.shape != log_b.shape:
        raise ValueError(f"log_lik_PG: expected shape {log_b.shape}, got {lik.shape}")
    n_goals = log_b.shape[-1]
    if log_prior.shape[-1] != n_goals or (log_prior.ndim == 2 and log_prior.shape != log_b.shape):
        raise ValueError(
            f"log_prior_PG: expected shape ({n_goals},) or {log_b.shape}, got {log_prior.shape}"
        )
    config.validate(n_goals)
    lam, eps = float(config.forgetting), float(config.floor)
    evidence = evidence_rows(lik)
    with np.errstate(invalid="ignore"):  # NaN and inf in rows that are no evidence
        x = lam * log_b + np.where(evidence[..., None], lik, 0.0)
        if lam < 1:  # (1 - λ) * -inf would be NaN at λ = 1: skip the term then
            target = _apply_floor(log_prior - _logsumexp(log_prior), eps, n_goals)
            x = x + (1.0 - lam) * target
        norm = _logsumexp(x)
    usable = evidence & np.isfinite(norm[..., 0])  # all -inf: nothing left possible, keep b
    updated = _apply_floor(x - np.where(usable[..., None], norm, 0.0), eps, n_goals)
    return np.where(usable[..., None], updated, log_b)


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


def belief_cross_entropy(log_belief_G: np.ndarray, true_index: int) -> float:
    """-log b(g*), in nats, for the true goal's index g* (inf when the belief rules it out)."""
    log_b = _belief_vector(log_belief_G)
    if isinstance(true_index, bool) or not 0 <= true_index < log_b.size:
        raise ValueError(f"true_index: expected 0..{log_b.size - 1}, got {true_index!r}")
    return float(-log_b[true_index])


def blend_goal_probs(
    log_belief_G: np.ndarray, goals: Sequence[str], mass: float = 0.99, max_goals: int = 8
) -> dict[str, float]:
    """The most probable goals, highest first, until they cover `mass` of the belief (at most
    `max_goals`), renormalised to sum to 1: the goal distribution the act pass blends impact
    networks by. An approximation by design: with a floor every goal has probability >= ε, and
    mixing all G impact networks on every step would cost G forwards for a few percent of mass."""
    log_b = _belief_vector(log_belief_G)
    if len(goals) != log_b.size:
        raise ValueError(f"goals: expected {log_b.size} goals, got {len(goals)}")
    if not _is_real(mass) or not 0 < mass <= 1:
        raise ValueError(f"mass: expected a number in (0, 1], got {mass!r}")
    if isinstance(max_goals, bool) or not isinstance(max_goals, int) or max_goals < 1:
        raise ValueError(f"max_goals: expected an integer >= 1, got {max_goals!r}")
    order = np.argsort(-log_b, kind="stable")[:max_goals].tolist()
    probs = np.exp(log_b[order]).tolist()
    kept: list[tuple[int, float]] = []
    covered = 0.0
    for g, p in zip(order, probs, strict=True):
        if p <= 0:
            break
        kept.append((g, p))
        covered += p
        if covered >= mass * (1 - 1e-12):  # rounding must not add a goal for 1e-16 of mass
            break
    if not kept:
        raise ValueError("log_belief_G: every goal has probability 0")
    total = math.fsum(p for _, p in kept)
    return {goals[g]: p / total for g, p in kept}
