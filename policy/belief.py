"""Online goal inference: a Bayesian belief over a partner's goal from its observed actions.

The paper lets a partner's goal be a probability distribution (§3.2, last paragraph) but does not
say where it comes from. Here it is the posterior of the partner's actions under its *task*
policies, each a Boltzmann policy of its task network (eq. 2):

    P(g | a_1..a_T) ∝ P(g) Π_t π_g(a_t | s_t),    π_g(a | s) = softmax(Q_g(s, ·) / α_g)[a]

kept in log space, with three changes a deployment needs (`BeliefConfig`):

- noise η in [0, 1): the likelihood of an action is the Boltzmann policy mixed with uniform
  action noise, p(a | s, g) = (1 - η) π_g(a | s) + η / |A| (`mix_uniform_noise`). A partner is
  never exactly the ego's copy of its networks (another training seed, a person, noise), and at
  the networks' α one unexpected action can cost a goal a factor of thousands; the mixture caps
  that cost at (1 - η + η/|A|) / (η/|A|), so no single action rules the true goal out.

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
| `mix_uniform_noise`          | log((1 - η) p + η/|A|) of log-likelihoods log p  | like input   |
| `update_log_belief`          | one step: forget, multiply, normalise, floor     | (P, G)/(G,)  |
| `PreparedUpdate`             | the same for fixed priors, checked once (faster) | (E, G)       |
| `evidence_rows`              | which likelihood rows count as evidence          | (P,)/()      |
| `PreparedUpdate.pruned`      | the update scoring only the active goals, with   | (E, G)       |
|                              | its error bound (`policy.belief_prune`)          |              |

What a belief says (`top_goals`, `belief_entropy`, `belief_summary`, `belief_cross_entropy`, the
blend's goal distribution `blend_goal_probs` / `blend_goal_weights`, and both for every row at
once, `belief_views`) lives in `policy.belief_views` and is re-exported here.

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
from policy.belief_compiled import compiled_update
from policy.belief_prune import PrunedUpdate, pruned_update
from policy.belief_views import (
    BeliefView,
    belief_cross_entropy,
    belief_entropy,
    belief_summary,
    belief_views,
    blend_goal_probs,
    blend_goal_weights,
    top_goals,
)

__all__ = [
    "BeliefConfig",
    "BeliefView",
    "PreparedUpdate",
    "belief_cross_entropy",
    "belief_entropy",
    "belief_summary",
    "belief_views",
    "blend_goal_probs",
    "blend_goal_weights",
    "boltzmann_log_likelihoods",
    "evidence_rows",
    "initial_log_belief",
    "mix_uniform_noise",
    "prior_log_probs",
    "top_goals",
    "update_log_belief",
]


def _is_real(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


# η of the default likelihood: the share of a partner's actions it expects to be uniformly random,
# whatever the goal (calibrated on partner types the inference report does not score,
# `reports/inference`)
DEFAULT_NOISE = 0.3


@dataclass(frozen=True)
class BeliefConfig:
    """How the belief is updated (module docstring); `validate` checks it for G goals."""

    forgetting: float = 0.95  # λ in (0, 1]: 1 = never forget
    floor: float = 1e-3  # ε in [0, 1/G): every goal keeps probability >= ε
    # α of the likelihood; None: the engine's default (`LIKELIHOOD_TEMPERING` × each task
    # network's training α, `services.engine.goal_inference`)
    temperature: float | None = None
    noise: float = DEFAULT_NOISE  # η in [0, 1): the likelihood's uniform action noise
    # goal pruning (`policy.belief_prune`): τ, goals below it are not scored while the step's
    # error bound stays <= δ, nor blended; 0 = off
    prune_below: float = 0.0
    prune_error: float = 0.05  # δ in (0, 1]: the bound on one step's total-variation error

    def validate(self, n_goals: int) -> None:
        """ValueError naming the field (`belief.forgetting`, ...) when a value is out of range."""
        lam, eps, alpha, eta = self.forgetting, self.floor, self.temperature, self.noise
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
        tau, delta = self.prune_below, self.prune_error
        if not _is_real(tau) or not (tau == 0 or eps < tau <= 1):
            raise ValueError(
                f"belief.prune_below: expected 0 (off) or a number in (floor, 1] = "
                f"({eps!r}, 1], got {tau!r}"
            )
        if tau > 0 and eps == 0:
            raise ValueError(
                "belief.prune_below: pruning needs belief.floor > 0 (a pruned goal keeps the "
                "floor's probability, from which the evidence can raise it again)"
            )
        if not _is_real(delta) or not 0 < delta <= 1:
            raise ValueError(f"belief.prune_error: expected a number in (0, 1], got {delta!r}")
        check_noise(eta, "belief.noise")


def check_noise(noise: object, field: str = "noise") -> float:
    """η as a float; ValueError naming `field` unless it is a real number in [0, 1)."""
    if not _is_real(noise) or not 0 <= noise < 1:  # type: ignore[operator]
        raise ValueError(f"{field}: expected a number in [0, 1), got {noise!r}")
    return float(noise)  # type: ignore[arg-type]


def mix_uniform_noise(log_lik: np.ndarray, noise: float, n_actions: int) -> np.ndarray:
    """log((1 - η) p + η / A) for log-likelihoods log p, elementwise (any shape): the likelihood
    of an action under "the policy, except that a share η of the actions is uniformly random".
    η = 0 returns `log_lik` itself (the same bits, no copy). -inf (p = 0) becomes log(η / A);
    NaN and +inf stay, so a row that was no evidence (`evidence_rows`) still is none."""
    if noise == 0:
        return log_lik
    spread = noise / n_actions
    if spread == 0.0:  # η / A below the smallest double: the mixture is the policy's share alone
        return log_lik + math.log1p(-noise)
    # In probabilities, which needs no floating-point guard (`logaddexp` on the log scale needs
    # `np.errstate` for NaN): exp of a log probability (<= 0, -inf, +inf or NaN) neither
    # overflows nor warns, and the log's argument is at least η / A > 0. p underflowing to 0
    # leaves log(η / A), the mixture's value there to double precision.
    return np.log(np.exp(log_lik) * (1.0 - noise) + spread)


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
    noise: float = 0.0,
    validate: bool = True,
) -> np.ndarray:
    """log π_g(a_p | s_p) = log softmax(Q_g(s_p) / α_g)[a_p] (eq. 2), shape (P, G); with
    `noise` η > 0, log((1 - η) π_g(a_p | s_p) + η / A) (`mix_uniform_noise`).

    `q_PGA` (P, G, A): goal g's task Q-values on partner p's view; `actions_P` (P,) ints in
    0..A-1; `alpha_G` (G,) or a scalar, positive and finite. Non-finite Q-values give a
    non-finite entry, which `update_log_belief` treats as no evidence for that row.
    `validate=False` skips the argument checks for a caller that made them already."""
    q = np.asarray(q_PGA, dtype=np.float64)
    actions = np.asarray(actions_P)
    alpha = np.asarray(alpha_G, dtype=np.float64)
    if validate:
        alpha = _check_likelihood_args(q, actions, alpha)
        check_noise(noise)
    elif alpha.ndim == 1:
        alpha = alpha[:, None]
    with np.errstate(over="ignore", invalid="ignore"):  # see the docstring: NaN is handled later
        z = q - q.max(axis=2, keepdims=True)
        z /= alpha  # <= 0, the arg-max exactly 0 (a tiny α gives -inf, never NaN)
        log_norm = np.log(np.exp(z).sum(axis=2))  # >= log 1 = 0: the arg-max term is exp(0)
    if q.shape[0] == 1:  # one partner (the usual case): plain indexing, the same numbers
        lik = z[0, :, int(actions[0])][None] - log_norm
    else:
        lik = z[np.arange(q.shape[0]), :, actions] - log_norm  # (P, G): advanced indices first
    return mix_uniform_noise(lik, noise, q.shape[2])


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
    return _updated(log_b, lik, _forgetting_pull(log_prior, lam, eps), lam, eps)


class PreparedUpdate:
    """`update_log_belief` for fixed priors and settings (a session's): the arguments are checked
    and the prior's forgetting term computed once, so a step costs a dozen numpy operations
    (or one compiled call, `policy.belief_compiled`) and gives the numbers of
    `update_log_belief`.

        update = PreparedUpdate(log_prior_PG, config)
        new_EG = update(log_belief_PG[rows], log_lik_EG, rows)  # rows: which partners acted
    """

    def __init__(self, log_prior_PG: np.ndarray, config: BeliefConfig) -> None:
        log_prior = _log_array(log_prior_PG, "log_prior_PG")
        if log_prior.ndim != 2:
            raise ValueError(f"log_prior_PG: expected shape (P, G), got {log_prior.shape}")
        config.validate(log_prior.shape[1])
        self.n_goals = log_prior.shape[1]
        self.forgetting, self.floor = float(config.forgetting), float(config.floor)
        self._pull_PG = _forgetting_pull(log_prior, self.forgetting, self.floor)

    def __call__(
        self, log_belief_EG: np.ndarray, log_lik_EG: np.ndarray, rows: Sequence[int] | None = None
    ) -> np.ndarray:
        """`update_log_belief(log_belief_EG, log_lik_EG, log_prior_PG[rows], config)` for
        float64 arrays of shape (E, G), E = len(rows) (rows None: all P, in order); the shapes
        are the caller's to check."""
        pull = self._pull_PG
        if pull is not None and rows is not None:
            pull = pull[rows]
        return _updated(log_belief_EG, log_lik_EG, pull, self.forgetting, self.floor)

    def pruned(
        self,
        log_belief_EG: np.ndarray,
        log_lik_EA: np.ndarray,
        active: np.ndarray,
        rows: Sequence[int] | None = None,
    ) -> PrunedUpdate:
        """`policy.belief_prune.pruned_update` of these rows with this session's prior and
        settings: the likelihoods `log_lik_EA` of the goals `active` only, and each row's bound
        on its distance to `self(log_belief_EG, full likelihoods, rows)`."""
        pull = self._pull_PG
        if pull is not None and rows is not None:
            pull = pull[rows]
        return pruned_update(log_belief_EG, log_lik_EA, active, pull, self.forgetting, self.floor)


def _forgetting_pull(log_prior: np.ndarray, lam: float, eps: float) -> np.ndarray | None:
    """(1 - λ) log prior_ε, the prior's share of an update (None at λ = 1, where
    (1 - λ) * -inf would be NaN: the term is skipped then)."""
    if lam >= 1:
        return None
    with np.errstate(invalid="ignore"):  # an all -inf prior row gives NaN: no evidence then
        target = _apply_floor(log_prior - _logsumexp(log_prior), eps, log_prior.shape[-1])
        return (1.0 - lam) * target


def _updated(
    log_b: np.ndarray, lik: np.ndarray, pull: np.ndarray | None, lam: float, eps: float
) -> np.ndarray:
    """The update's arithmetic (`update_log_belief`). When every entry is finite (every row is
    evidence and normalisable: the usual case) the masks are skipped; the operations, hence the
    bits, are those of the general path. That case runs compiled where it can
    (`policy.belief_compiled`, equal within 1e-12)."""
    fast = compiled_update(log_b, lik, pull, lam, eps)
    return reference_update(log_b, lik, pull, lam, eps) if fast is None else fast


def reference_update(
    log_b: np.ndarray, lik: np.ndarray, pull: np.ndarray | None, lam: float, eps: float
) -> np.ndarray:
    """`_updated` in numpy: the compiled update's reference, and the rows it leaves (a
    non-finite likelihood or update)."""
    n_goals = log_b.shape[-1]
    if np.isfinite(lik).all():
        x = lam * log_b + lik
        if pull is not None:
            x = x + pull
        if np.isfinite(x).all():
            top = x.max(axis=-1, keepdims=True)
            norm = top + np.log(np.exp(x - top).sum(axis=-1, keepdims=True))
            return _apply_floor(x - norm, eps, n_goals)
    evidence = evidence_rows(lik)
    with np.errstate(invalid="ignore"):  # NaN and inf in rows that are no evidence
        x = lam * log_b + np.where(evidence[..., None], lik, 0.0)
        if pull is not None:
            x = x + pull
        norm = _logsumexp(x)
    usable = evidence & np.isfinite(norm[..., 0])  # all -inf: nothing left possible, keep b
    updated = _apply_floor(x - np.where(usable[..., None], norm, 0.0), eps, n_goals)
    return np.where(usable[..., None], updated, log_b)
