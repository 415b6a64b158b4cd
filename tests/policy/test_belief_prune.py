"""Goal pruning (`policy.belief_prune`): on random beliefs, priors, settings and Boltzmann
likelihoods, the pruned update is within its stated bound of the exact update (total
variation), its distance is exactly (1 - Gε) times the pruned goals' true share, the bound is
attained where every pruned goal gives the action probability 1, and it is at most the a-priori
form with the likelihood ratio A exp(ΔQ / α). The pruned blend's goal distribution is the
belief's minus the goals below τ, and the expected impact Q it gives is within the stated
bound of the whole belief's."""

from __future__ import annotations

import numpy as np
import pytest

from policy.belief import (
    BeliefConfig,
    PreparedUpdate,
    blend_goal_weights,
    boltzmann_log_likelihoods,
    initial_log_belief,
    update_log_belief,
)
from policy.belief_prune import active_goals

CASES = 1500


def tv(log_p: np.ndarray, log_q: np.ndarray) -> np.ndarray:
    """Total-variation distance per row."""
    return 0.5 * np.abs(np.exp(log_p) - np.exp(log_q)).sum(axis=-1)


def random_case(rng: np.random.Generator) -> dict:
    """A belief (E, G) reached by a few exact updates from a random prior, Boltzmann
    likelihoods (E, G) of one action on random Q-values, a threshold and the settings."""
    n_goals = int(rng.integers(2, 80))
    n_rows = int(rng.integers(1, 5))
    n_actions = int(rng.integers(2, 7))
    eps = float(rng.choice([1e-5, 1e-4, 1e-3 * rng.random()])) / max(1.0, n_goals / 35)
    config = BeliefConfig(
        forgetting=float(rng.choice([1.0, 0.95, rng.uniform(0.5, 1.0)])), floor=eps
    )
    prior = rng.dirichlet(np.full(n_goals, rng.choice([0.2, 1.0, 5.0])), size=n_rows)
    log_prior = np.log(prior)
    log_b = initial_log_belief(log_prior, config)
    alpha = rng.uniform(0.02, 1.0, size=n_goals)
    spread = rng.uniform(0.1, 3.0)
    for _ in range(int(rng.integers(0, 6))):  # a history: the belief concentrates
        q = rng.normal(0.0, spread, size=(n_rows, n_goals, n_actions))
        a = rng.integers(n_actions, size=n_rows)
        log_b = update_log_belief(log_b, boltzmann_log_likelihoods(q, a, alpha), log_prior, config)
    q = rng.normal(0.0, spread, size=(n_rows, n_goals, n_actions))
    actions = rng.integers(n_actions, size=n_rows)
    tau = float(rng.uniform(eps * 1.01, 0.5))
    return {
        "config": config,
        "log_prior": log_prior,
        "log_b": log_b,
        "q": q,
        "alpha": alpha,
        "lik": boltzmann_log_likelihoods(q, actions, alpha),
        "tau": tau,
    }


def test_the_pruned_update_is_within_its_bound_of_the_exact_one() -> None:
    rng = np.random.default_rng(20)
    pruned_rows = 0
    for _ in range(CASES):
        c = random_case(rng)
        config, log_b, lik = c["config"], c["log_b"], c["lik"]
        update = PreparedUpdate(c["log_prior"], config)
        exact = update(log_b, lik)
        active = active_goals(log_b, c["tau"])
        step = update.pruned(log_b, lik[:, active], active)
        got = tv(step.log_belief_EG, exact)
        assert np.all(np.isfinite(step.bound_E))
        assert np.all(got <= step.bound_E + 1e-12), (got, step.bound_E)
        # the distance is exactly (1 - Gε) times the pruned goals' true share m
        n_goals = log_b.shape[1]
        pruned = np.setdiff1d(np.arange(n_goals), active)
        pull = update._pull_PG
        x = config.forgetting * log_b + (0.0 if pull is None else pull) + lik
        w = np.exp(x - x.max(axis=1, keepdims=True))
        m = w[:, pruned].sum(axis=1) / w.sum(axis=1)
        np.testing.assert_allclose(got, (1 - n_goals * config.floor) * m, rtol=1e-9, atol=1e-13)
        # every goal's probability is >= the floor, the rows sum to 1
        assert np.all(step.log_belief_EG >= np.log(config.floor) - 1e-12)
        np.testing.assert_allclose(np.exp(step.log_belief_EG).sum(axis=1), 1.0, atol=1e-12)
        pruned_rows += len(pruned) > 0
    assert pruned_rows > CASES // 2  # most cases prune something


def test_the_bound_is_at_most_its_a_priori_form_with_the_likelihood_ratio() -> None:
    """β <= P_S / (P_A ℓ_min + P_S), ℓ_min = min over active goals of exp(-ΔQ_g / α_g) / A:
    the pruned mass weighed by the worst likelihood ratio A exp(ΔQ / α)."""
    rng = np.random.default_rng(21)
    for _ in range(CASES):
        c = random_case(rng)
        config, log_b, q, alpha = c["config"], c["log_b"], c["q"], c["alpha"]
        update = PreparedUpdate(c["log_prior"], config)
        active = active_goals(log_b, c["tau"])
        bound = update.pruned(log_b, c["lik"][:, active], active).bound_E
        n_goals, n_actions = log_b.shape[1], q.shape[2]
        pull = update._pull_PG
        log_p = config.forgetting * log_b + (0.0 if pull is None else pull)
        p = np.exp(log_p)
        pruned = np.setdiff1d(np.arange(n_goals), active)
        span = q.max(axis=2) - q.min(axis=2)  # (E, G)
        ell_min = (np.exp(-span / alpha) / n_actions)[:, active].min(axis=1)
        p_s, p_a = p[:, pruned].sum(axis=1), p[:, active].sum(axis=1)
        a_priori = (1 - n_goals * config.floor) * p_s / (p_a * ell_min + p_s)
        assert np.all(bound <= a_priori * (1 + 1e-9) + 1e-15)


def test_the_bound_is_attained_when_every_pruned_goal_predicts_the_action() -> None:
    """The constructed worst case: each pruned goal gives the action probability 1 (log 0),
    each active goal a small one; the distance equals the bound."""
    rng = np.random.default_rng(22)
    for n_goals, eps in ((35, 1e-3), (350, 1e-4), (10, 1e-2)):
        config = BeliefConfig(forgetting=0.95, floor=eps)
        log_prior = np.log(np.full((1, n_goals), 1 / n_goals))
        probs = rng.dirichlet(np.full(n_goals, 0.1))[None]
        log_b = initial_log_belief(np.log(probs), config)
        update = PreparedUpdate(log_prior, config)
        active = active_goals(log_b, 0.05)
        assert 0 < len(active) < n_goals
        lik = np.zeros((1, n_goals))  # probability 1 for the pruned goals ...
        lik[:, active] = np.log(rng.uniform(0.01, 0.2, size=len(active)))  # ... small for A
        step = update.pruned(log_b, lik[:, active], active)
        got = tv(step.log_belief_EG, update(log_b, lik))
        np.testing.assert_allclose(got, step.bound_E, rtol=1e-9)
        assert step.bound_E[0] > 0.01  # a real gap, not a rounding


def test_every_goal_active_is_the_exact_update() -> None:
    rng = np.random.default_rng(23)
    for _ in range(200):
        c = random_case(rng)
        update = PreparedUpdate(c["log_prior"], c["config"])
        every = np.arange(c["log_b"].shape[1])
        step = update.pruned(c["log_b"], c["lik"], every)
        np.testing.assert_allclose(step.log_belief_EG, update(c["log_b"], c["lik"]), atol=1e-12)
        assert np.all(step.bound_E == 0)


def test_active_goals_are_those_at_or_above_tau_and_each_rows_top() -> None:
    log_b = np.log(np.array([[0.6, 0.3, 0.05, 0.05], [0.04, 0.06, 0.45, 0.45]]))
    assert active_goals(log_b, 0.3).tolist() == [0, 1, 2, 3]
    assert active_goals(log_b, 0.5).tolist() == [0, 2]  # row 2's top: its first of the tie
    assert active_goals(log_b[:1], 0.99).tolist() == [0]


def test_a_row_without_finite_evidence_gets_an_infinite_bound() -> None:
    config = BeliefConfig(floor=1e-3)
    log_prior = np.log(np.full((1, 4), 0.25))
    update = PreparedUpdate(log_prior, config)
    log_b = initial_log_belief(np.log(np.array([[0.7, 0.2, 0.05, 0.05]])), config)
    step = update.pruned(log_b, np.array([[np.nan, -1.0]]), np.array([0, 1]))
    assert step.bound_E[0] == np.inf  # the session scores every goal then
    np.testing.assert_array_equal(step.log_belief_EG, log_b)


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"prune_below": -0.1}, "belief.prune_below"),
        ({"prune_below": 0.0005}, "belief.prune_below"),  # not above the floor (1e-3)
        ({"prune_below": 1.01}, "belief.prune_below"),
        ({"prune_below": True}, "belief.prune_below"),
        ({"prune_below": float("nan")}, "belief.prune_below"),
        ({"prune_below": 0.1, "floor": 0.0}, "belief.prune_below"),
        ({"prune_error": 0.0}, "belief.prune_error"),
        ({"prune_error": 1.5}, "belief.prune_error"),
        ({"prune_error": "0.1"}, "belief.prune_error"),
    ],
)
def test_bad_pruning_settings_name_their_field(changes: dict, field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field}:"):
        BeliefConfig(**changes).validate(35)


def test_the_pruned_blend_is_the_belief_without_the_goals_below_tau() -> None:
    """The blend's goal distribution leaves out the goals below τ (never the top one) and
    renormalises: its distance to the whole belief is the mass left out, and the expected
    impact Q-vector it gives moves by at most that distance times the spread of the goals'
    Q-vectors (max over goals g, h and actions of |Q_g - Q_h|)."""
    rng = np.random.default_rng(24)
    for _ in range(CASES):
        n_goals = int(rng.integers(2, 80))
        probs = rng.dirichlet(np.full(n_goals, rng.choice([0.1, 0.5, 2.0])))
        log_b = np.log(probs)
        tau = float(rng.uniform(0.0, 0.6))
        kept, weights = blend_goal_weights(log_b, below=tau)
        assert int(np.argmax(probs)) in kept
        assert all(probs[g] >= tau for g in kept if g != int(np.argmax(probs)))
        assert all(probs[g] < tau for g in set(range(n_goals)) - set(kept))
        dropped = probs[np.setdiff1d(np.arange(n_goals), kept)].sum()
        w = np.zeros(n_goals)
        w[kept] = weights
        distance = 0.5 * np.abs(w - probs).sum()
        np.testing.assert_allclose(distance, dropped, atol=1e-12)
        q_GA = rng.normal(0.0, rng.uniform(0.1, 5.0), size=(n_goals, 5))
        spread = (q_GA.max(axis=0) - q_GA.min(axis=0)).max()
        moved = np.abs(w @ q_GA - probs @ q_GA).max()
        assert moved <= distance * spread + 1e-12
        # with a cap on the mass left out: pruned within it, else the whole belief
        cap = float(rng.uniform(0.0, 0.3))
        capped, _ = blend_goal_weights(log_b, below=tau, below_mass=cap)
        positive = [g for g in range(n_goals) if np.exp(log_b[g]) > 0]  # dirichlet may underflow
        assert capped == (kept if dropped <= cap else positive)
