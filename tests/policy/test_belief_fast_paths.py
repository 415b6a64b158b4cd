"""The belief's per-step shortcuts give the numbers of the plain functions, bit for bit:
`update_log_belief` (whose all-finite case skips the masks) = the masked arithmetic written out
below, `PreparedUpdate` = `update_log_belief`, `belief_summary` = `top_goals` +
`belief_entropy`, `blend_goal_weights` = `blend_goal_probs`, `belief_views` = both per row. Random beliefs, likelihoods with
-inf / NaN / +inf entries, forgetting 1 and floor 0 included (the shortcuts branch on exactly
those cases). The numpy code throughout (`reference_update`, `reference_views` where the
compiled kernel would take the case): the compiled kernel is held to it within a tolerance by
tests/policy/test_belief_compiled.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from policy.belief import (
    BeliefConfig,
    PreparedUpdate,
    belief_entropy,
    belief_summary,
    belief_views,
    blend_goal_probs,
    blend_goal_weights,
    initial_log_belief,
    reference_update,
    top_goals,
    update_log_belief,
)
from policy.belief_views import reference_views

CONFIGS = [
    BeliefConfig(),
    BeliefConfig(forgetting=1.0, floor=0.0),
    BeliefConfig(forgetting=0.7, floor=0.0),
    BeliefConfig(forgetting=1.0, floor=0.01),
]


def _random_log_probs(rng: np.random.Generator, shape: tuple[int, ...], zeros: bool) -> np.ndarray:
    probs = rng.dirichlet(np.full(shape[-1], 0.5), size=shape[:-1])
    if zeros:  # some goals ruled out (a zero prior, or a belief without a floor)
        probs[rng.random(probs.shape) < 0.2] = 0.0
        probs[..., 0] += 0.1  # never all zero
        probs /= probs.sum(axis=-1, keepdims=True)
    with np.errstate(divide="ignore"):
        return np.log(probs)


def _random_likelihoods(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    lik = np.log(rng.dirichlet(np.ones(shape[1]), size=shape[0]))
    kind = rng.integers(6)
    if kind == 1:
        lik[0, rng.integers(shape[1])] = -np.inf
    elif kind == 2:
        lik[0, rng.integers(shape[1])] = np.nan
    elif kind == 3:
        lik[0, rng.integers(shape[1])] = np.inf
    elif kind == 4:
        lik[0] = -np.inf
    return lik


def _logsumexp(x: np.ndarray) -> np.ndarray:
    top = x.max(axis=-1, keepdims=True)
    safe = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return safe + np.log(np.exp(x - safe).sum(axis=-1, keepdims=True))


def _floored(log_b: np.ndarray, eps: float) -> np.ndarray:
    if eps == 0:
        return log_b
    return np.logaddexp(math.log1p(-log_b.shape[-1] * eps) + log_b, math.log(eps))


def _reference_update(
    log_b: np.ndarray, lik: np.ndarray, log_prior: np.ndarray, config: BeliefConfig
) -> np.ndarray:
    """The update with every mask applied (no shortcut): forget, multiply, normalise, floor."""
    lam, eps = config.forgetting, config.floor
    evidence = ~np.isnan(lik).any(-1) & ~(lik == np.inf).any(-1) & np.isfinite(lik).any(-1)
    with np.errstate(invalid="ignore"):
        x = lam * log_b + np.where(evidence[..., None], lik, 0.0)
        if lam < 1:
            x = x + (1.0 - lam) * _floored(log_prior - _logsumexp(log_prior), eps)
        norm = _logsumexp(x)
    usable = evidence & np.isfinite(norm[..., 0])
    updated = _floored(x - np.where(usable[..., None], norm, 0.0), eps)
    return np.where(usable[..., None], updated, log_b)


@pytest.mark.parametrize("config", CONFIGS)
def test_update_equals_the_fully_masked_arithmetic(config: BeliefConfig) -> None:
    rng = np.random.default_rng(3)
    for trial in range(300):
        n_partners, n_goals = int(rng.integers(1, 5)), int(rng.integers(2, 40))
        zeros = config.floor == 0 and trial % 3 == 0
        log_prior_PG = _random_log_probs(rng, (n_partners, n_goals), zeros)
        log_b_PG = initial_log_belief(_random_log_probs(rng, (n_partners, n_goals), zeros), config)
        lik_PG = _random_likelihoods(rng, (n_partners, n_goals))
        with np.errstate(invalid="ignore"):
            pull = PreparedUpdate(log_prior_PG, config)._pull_PG
            got = reference_update(log_b_PG, lik_PG, pull, config.forgetting, config.floor)
            expected = _reference_update(log_b_PG, lik_PG, log_prior_PG, config)
            compiled = update_log_belief(log_b_PG, lik_PG, log_prior_PG, config)
        np.testing.assert_array_equal(got, expected)
        np.testing.assert_allclose(compiled, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("config", CONFIGS)
def test_prepared_update_equals_update_log_belief(config: BeliefConfig) -> None:
    rng = np.random.default_rng(7)
    for trial in range(300):
        n_partners, n_goals = int(rng.integers(1, 5)), int(rng.integers(2, 40))
        zeros = config.floor == 0 and trial % 3 == 0
        log_prior_PG = _random_log_probs(rng, (n_partners, n_goals), zeros)
        update = PreparedUpdate(log_prior_PG, config)
        log_b_PG = initial_log_belief(_random_log_probs(rng, (n_partners, n_goals), zeros), config)
        lik_PG = _random_likelihoods(rng, (n_partners, n_goals))
        with np.errstate(invalid="ignore"):  # degenerate rows: the general path's business
            expected = update_log_belief(log_b_PG, lik_PG, log_prior_PG, config)
            np.testing.assert_array_equal(update(log_b_PG, lik_PG), expected)
            rows = sorted(rng.choice(n_partners, int(rng.integers(1, n_partners + 1)), False))
            np.testing.assert_array_equal(
                update(log_b_PG[rows], lik_PG[rows], rows),
                update_log_belief(log_b_PG[rows], lik_PG[rows], log_prior_PG[rows], config),
            )


def test_prepared_update_checks_its_prior_and_config() -> None:
    with pytest.raises(ValueError, match=r"^log_prior_PG:"):
        PreparedUpdate(np.zeros(3), BeliefConfig())
    with pytest.raises(ValueError, match=r"^belief.floor:"):
        PreparedUpdate(np.zeros((1, 3)), BeliefConfig(floor=0.5))


def test_belief_summary_equals_top_goals_and_entropy() -> None:
    rng = np.random.default_rng(11)
    for trial in range(500):
        n_goals = int(rng.integers(1, 40))
        log_b = _random_log_probs(rng, (n_goals,), zeros=trial % 4 == 0)
        if trial % 5 == 0:  # ties
            log_b[: n_goals // 2] = log_b[0]
        goals = [f"g{g}" for g in range(n_goals)]
        k = int(rng.integers(1, 5))
        top, entropy = belief_summary(log_b, goals, k)
        assert top == top_goals(log_b, goals, k)
        assert entropy == belief_entropy(log_b)
    with pytest.raises(ValueError, match=r"^goals:"):
        belief_summary(np.zeros(2), ["a"])


def test_blend_goal_weights_are_the_blend_distribution() -> None:
    rng = np.random.default_rng(5)
    for trial in range(300):
        n_goals = int(rng.integers(1, 40))
        log_b = _random_log_probs(rng, (n_goals,), zeros=trial % 3 == 0)
        goals = [f"g{g}" for g in range(n_goals)]
        mass = float(rng.choice([1.0, 0.99, 0.5]))
        max_goals = [None, 1, 8, n_goals][trial % 4]
        kept, probs = blend_goal_weights(log_b, mass, max_goals)
        assert kept == sorted(kept)
        assert dict(zip([goals[g] for g in kept], probs, strict=True)) == blend_goal_probs(
            log_b, goals, mass, max_goals
        )


def test_belief_views_equal_blend_weights_and_summary_row_by_row() -> None:
    """Bit for bit, with several rows (one exp, sort and sum for all of them), zeros in some
    rows only (the masked entropy then serves every row), ties and every blend setting."""
    rng = np.random.default_rng(13)
    for trial in range(400):
        n_partners, n_goals = int(rng.integers(1, 6)), int(rng.integers(1, 40))
        log_b_PG = _random_log_probs(rng, (n_partners, n_goals), zeros=False)
        if trial % 3 == 0:  # goals ruled out in one row
            log_b_PG[0] = _random_log_probs(rng, (n_goals,), zeros=True)
        if trial % 5 == 0:  # ties
            log_b_PG[:, : n_goals // 2] = log_b_PG[:, :1]
        goals = [f"g{g}" for g in range(n_goals)]
        k = int(rng.integers(1, 5))
        mass = float(rng.choice([1.0, 0.99, 0.5]))
        max_goals = [None, 1, 8, n_goals][trial % 4]
        views = reference_views(log_b_PG, goals, k, mass, max_goals)
        assert len(views) == n_partners
        for row, view in zip(log_b_PG, views, strict=True):
            assert (view.blend_goals, view.blend_probs) == blend_goal_weights(row, mass, max_goals)
            assert (view.top, view.entropy) == belief_summary(row, goals, k)


def test_belief_views_check_their_arguments() -> None:
    assert belief_views(np.zeros((0, 3)), ["a", "b", "c"]) == []
    with pytest.raises(ValueError, match=r"^log_belief_PG:"):
        belief_views(np.zeros(3), ["a", "b", "c"])
    with pytest.raises(ValueError, match=r"^goals:"):
        belief_views(np.zeros((1, 2)), ["a"])
    with pytest.raises(ValueError, match=r"^k:"):
        belief_views(np.zeros((1, 1)), ["a"], k=0)
    with pytest.raises(ValueError, match=r"^mass:"):
        belief_views(np.zeros((1, 1)), ["a"], mass=0.0)
    with pytest.raises(ValueError, match=r"^max_goals:"):
        belief_views(np.zeros((1, 1)), ["a"], max_goals=0)
    with pytest.raises(ValueError, match=r"every goal has probability 0"):
        belief_views(np.full((1, 2), -np.inf), ["a", "b"])
