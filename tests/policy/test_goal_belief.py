"""policy.belief: a hand-computed 3-goal example, the plain Bayes product, forgetting and floor,
log-space stability, evidence that is no evidence, the prior, summaries and config errors."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from policy.belief import (
    BeliefConfig,
    belief_cross_entropy,
    belief_entropy,
    blend_goal_probs,
    boltzmann_log_likelihoods,
    evidence_rows,
    initial_log_belief,
    mix_uniform_noise,
    prior_log_probs,
    top_goals,
    update_log_belief,
)
from policy.maths import boltzmann

GOALS3 = ("x", "y", "z")
LN3 = math.log(3.0)
LN2 = math.log(2.0)
# α = 1, two actions: π_x = [3/4, 1/4], π_y = [1/2, 1/2], π_z = [1/4, 3/4]
Q_3GOALS_1GA = np.array([[[LN3, 0.0], [0.0, 0.0], [0.0, LN3]]])
BAYES = BeliefConfig(forgetting=1.0, floor=0.0)


def _lik(actions: list[int], q_PGA: np.ndarray = Q_3GOALS_1GA, alpha: float = 1.0) -> np.ndarray:
    return boltzmann_log_likelihoods(q_PGA, np.array(actions), np.full(q_PGA.shape[1], alpha))


def _uniform(n_goals: int = 3) -> np.ndarray:
    return np.full(n_goals, -math.log(n_goals))


# --- hand-computed numbers --------------------------------------------------------------------


def test_likelihoods_of_the_three_goal_example() -> None:
    np.testing.assert_allclose(np.exp(_lik([0])), [[0.75, 0.5, 0.25]], rtol=1e-12)
    np.testing.assert_allclose(np.exp(_lik([1])), [[0.25, 0.5, 0.75]], rtol=1e-12)


def test_one_update_is_the_normalised_product() -> None:
    # uniform prior × [3/4, 1/2, 1/4], normalised by 3/2: [1/2, 1/3, 1/6]
    b = update_log_belief(_uniform()[None], _lik([0]), _uniform(), BAYES)
    np.testing.assert_allclose(np.exp(b), [[1 / 2, 1 / 3, 1 / 6]], rtol=1e-12)


def test_the_floor_mixes_with_the_uniform_distribution() -> None:
    # ε = 0.01, G = 3: b'' = 0.97 b' + 0.01 = [0.495, 0.3333.., 0.171666..]
    config = BeliefConfig(forgetting=1.0, floor=0.01)
    b = update_log_belief(_uniform()[None], _lik([0]), _uniform(), config)
    np.testing.assert_allclose(np.exp(b), [[0.495, 0.97 / 3 + 0.01, 0.97 / 6 + 0.01]], rtol=1e-12)
    np.testing.assert_allclose(np.exp(b), [[0.495, 0.3333333333333, 0.1716666666667]], rtol=1e-12)


def test_forgetting_pulls_toward_the_prior_by_hand() -> None:
    # λ = 0.5, ε = 0, uniform prior, action 0 twice.
    # step 1: b1 ∝ (1/3)^0.5 (1/3)^0.5 lik = lik / 3 -> [1/2, 1/3, 1/6] (as without forgetting)
    # step 2: b2 ∝ b1^0.5 (1/3)^0.5 lik = sqrt([1/6, 1/9, 1/18]) [3/4, 1/2, 1/4]
    #         = [√6/8, 1/6, √2/24] = [0.306186, 0.166667, 0.058926], sum 0.531779
    #         -> [0.575778, 0.313414, 0.110808]
    config = BeliefConfig(forgetting=0.5, floor=0.0)
    b1 = update_log_belief(_uniform(), _lik([0])[0], _uniform(), config)
    np.testing.assert_allclose(np.exp(b1), [1 / 2, 1 / 3, 1 / 6], rtol=1e-12)
    b2 = update_log_belief(b1, _lik([0])[0], _uniform(), config)
    np.testing.assert_allclose(np.exp(b2), [0.5757777850, 0.3134137286, 0.1108084864], rtol=1e-9)


def test_without_evidence_forgetting_returns_to_the_prior() -> None:
    # a likelihood that is the same for every goal carries no information: only λ acts,
    # log b_k = λ^k log b_0 + (1 - λ^k) log prior (up to normalisation)
    prior = np.log([0.6, 0.3, 0.1])
    b = np.log([0.1, 0.1, 0.8])
    config = BeliefConfig(forgetting=0.8, floor=0.0)
    for _ in range(200):
        b = update_log_belief(b, np.full(3, -1.6), prior, config)
    np.testing.assert_allclose(np.exp(b), [0.6, 0.3, 0.1], rtol=1e-9)


# --- the plain Bayes product ----------------------------------------------------------------


def test_forgetting_one_equals_the_naive_bayes_product() -> None:
    rng = np.random.default_rng(3)
    n_goals, n_actions, steps, alpha_G = 6, 5, 25, rng.uniform(0.3, 2.0, 6)
    prior = np.array([0.3, 0.05, 0.25, 0.1, 0.2, 0.1])
    log_b = initial_log_belief(np.log(prior), BAYES)
    naive = prior.copy()
    for _ in range(steps):
        q_GA = rng.normal(size=(n_goals, n_actions))
        action = int(rng.integers(n_actions))
        log_lik = boltzmann_log_likelihoods(q_GA[None], np.array([action]), alpha_G)[0]
        log_b = update_log_belief(log_b, log_lik, np.log(prior), BAYES)
        # the naive product with plain probabilities: P(g) Π_t π_g(a_t | s_t)
        for g in range(n_goals):
            pi = np.exp(q_GA[g] / alpha_G[g]) / np.exp(q_GA[g] / alpha_G[g]).sum()
            naive[g] *= pi[action]
    np.testing.assert_allclose(np.exp(log_b), naive / naive.sum(), rtol=1e-9)


def test_likelihoods_match_log_of_the_policy_and_skip_checks_gives_the_same() -> None:
    rng = np.random.default_rng(0)
    q_PGA = rng.normal(size=(3, 4, 5)) * 10
    alpha_G = np.array([0.1, 0.5, 1.0, 3.0])
    actions = np.array([4, 0, 2])
    got = boltzmann_log_likelihoods(q_PGA, actions, alpha_G)
    for p in range(3):
        for g in range(4):
            pi = boltzmann(q_PGA[p, g], alpha_G[g])
            assert got[p, g] == pytest.approx(math.log(pi[actions[p]]), rel=1e-12)
    unchecked = boltzmann_log_likelihoods(q_PGA, actions, alpha_G, validate=False)
    np.testing.assert_array_equal(unchecked, got)
    scalar = boltzmann_log_likelihoods(q_PGA, actions, 0.5)
    np.testing.assert_array_equal(scalar[:, 1], got[:, 1])


# --- the likelihood mixed with uniform action noise -------------------------------------------


def test_the_noisy_likelihood_of_the_three_goal_example_by_hand() -> None:
    # η = 0.2, A = 2: (1 - η) π + η / A = 0.8 [3/4, 1/2, 1/4] + 0.1 = [0.7, 0.5, 0.3]
    lik = boltzmann_log_likelihoods(Q_3GOALS_1GA, np.array([0]), np.ones(3), noise=0.2)
    np.testing.assert_allclose(np.exp(lik), [[0.7, 0.5, 0.3]], rtol=1e-12)
    b = update_log_belief(_uniform()[None], lik, _uniform(), BAYES)
    np.testing.assert_allclose(np.exp(b), [[0.7 / 1.5, 0.5 / 1.5, 0.3 / 1.5]], rtol=1e-12)


@pytest.mark.parametrize("noise", [0.01, 0.1, 0.5, 0.9])
def test_noisy_likelihoods_are_the_formula_on_the_policy(noise: float) -> None:
    # p(a | s, g) = (1 - η) softmax(Q_g(s) / α_g)[a] + η / A, computed directly in probabilities
    rng = np.random.default_rng(3)
    q_PGA = rng.normal(size=(3, 4, 5)) * 10
    alpha_G = np.array([0.05, 0.5, 1.0, 3.0])
    actions = np.array([4, 0, 2])
    got = boltzmann_log_likelihoods(q_PGA, actions, alpha_G, noise=noise)
    for p in range(3):
        for g in range(4):
            pi = boltzmann(q_PGA[p, g], alpha_G[g])
            want = (1 - noise) * pi[actions[p]] + noise / 5
            assert got[p, g] == pytest.approx(math.log(want), rel=1e-12, abs=1e-14)
    plain = boltzmann_log_likelihoods(q_PGA, actions, alpha_G)
    np.testing.assert_array_equal(mix_uniform_noise(plain, noise, 5), got)
    unchecked = boltzmann_log_likelihoods(q_PGA, actions, alpha_G, noise=noise, validate=False)
    np.testing.assert_array_equal(unchecked, got)


def test_the_noise_caps_what_one_action_can_cost_a_goal() -> None:
    # an action the goal's policy never takes (α tiny: p = 0, log p = -inf): log(η / A) instead,
    # so the log-odds against the goal that does take it grow by at most log((1 - η + η/A) / (η/A))
    q_1GA = np.array([[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    noise = 0.3
    plain = boltzmann_log_likelihoods(q_1GA, np.array([1]), np.full(2, 1e-310))
    assert plain[0, 0] == -np.inf
    lik = boltzmann_log_likelihoods(q_1GA, np.array([1]), np.full(2, 1e-310), noise=noise)
    assert lik[0, 0] == pytest.approx(math.log(noise / 3), rel=1e-12)
    assert lik[0, 1] - lik[0, 0] == pytest.approx(math.log((1 - noise + noise / 3) / (noise / 3)))
    b = update_log_belief(_uniform(2), lik[0], _uniform(2), BAYES)
    assert np.exp(b[0]) == pytest.approx(1 / 9, rel=1e-12)  # 0.1 / (0.1 + 0.8)


def test_mixing_keeps_what_is_no_evidence_and_zero_noise_is_the_identity() -> None:
    lik = np.array([[np.nan, -1.0], [np.inf, -2.0], [-np.inf, -np.inf]])
    mixed = mix_uniform_noise(lik, 0.1, 5)
    assert np.isnan(mixed[0, 0]) and mixed[1, 0] == np.inf
    np.testing.assert_allclose(mixed[2], math.log(0.02), rtol=1e-12)
    np.testing.assert_array_equal(evidence_rows(mixed), evidence_rows(lik) | [False, False, True])
    assert mix_uniform_noise(lik, 0.0, 5) is lik
    tiny = 5e-324  # η / A below the smallest double: the policy's share alone, no log(0)
    with np.errstate(all="raise"):
        mixed = mix_uniform_noise(np.array([-1.0, 0.0, -np.inf]), tiny, 5)
    np.testing.assert_allclose(mixed, [-1.0, 0.0, -np.inf], rtol=1e-15, atol=1e-300)
    with pytest.raises(ValueError, match=r"^noise: expected"):
        boltzmann_log_likelihoods(Q_3GOALS_1GA, np.array([0]), np.ones(3), noise=1.0)


# --- stability, floor, recovery --------------------------------------------------------------


def test_huge_q_and_tiny_alpha_stay_finite_and_pick_the_right_goal() -> None:
    # Q of 1e4 with α = 1e-6: (Q - max Q) / α = -1e10; nothing overflows, nothing is NaN
    q_1GA = np.array([[[1e4, -1e4, 0.0], [-1e4, 1e4, 0.0], [1e4, 1e4 - 1.0, 1e4]]])
    lik = boltzmann_log_likelihoods(q_1GA, np.array([0]), np.full(3, 1e-6))
    assert not np.isnan(lik).any()
    assert lik[0, 0] == pytest.approx(0.0, abs=1e-12)  # certain
    assert lik[0, 1] == pytest.approx(-2e10, rel=1e-12)
    assert lik[0, 2] == pytest.approx(-math.log(2.0), rel=1e-9)  # a tie of two actions
    for config in (BAYES, BeliefConfig()):
        b = update_log_belief(_uniform(), lik[0], _uniform(), config)
        assert np.isfinite(b).all()
        assert np.exp(b).sum() == pytest.approx(1.0, abs=1e-12)
        assert int(np.argmax(b)) == 0
    # α so small that the division overflows: -inf, still no NaN, and the belief is usable
    lik = boltzmann_log_likelihoods(q_1GA, np.array([0]), np.full(3, 1e-310))
    assert not np.isnan(lik).any() and lik[0, 1] == -np.inf
    b = update_log_belief(_uniform(), lik[0], _uniform(), BeliefConfig(floor=0.01))
    assert np.isfinite(b).all() and np.exp(b).min() >= 0.01 * (1 - 1e-12)


def test_the_floor_holds_after_1000_adversarial_updates() -> None:
    rng = np.random.default_rng(7)
    n_goals, eps = 35, 1e-3
    config = BeliefConfig(forgetting=0.95, floor=eps)
    prior = np.log(rng.dirichlet(np.ones(n_goals)))
    b = initial_log_belief(prior, config)
    for step in range(1000):
        victim = step % n_goals  # every goal is hammered in turn, some by -1e300
        lik = rng.normal(size=n_goals) * 50
        lik[victim] = -1e300 if step % 3 == 0 else -np.inf if step % 3 == 1 else -1e6
        b = update_log_belief(b, lik, prior, config)
        probs = np.exp(b)
        assert probs.min() >= eps * (1 - 1e-9), step
        assert probs.sum() == pytest.approx(1.0, abs=1e-9)


def test_a_goal_ruled_out_for_200_steps_comes_back_when_evidence_turns() -> None:
    config = BeliefConfig(forgetting=1.0, floor=1e-3)  # no forgetting: the floor alone saves it
    b = _uniform()
    against = np.log([0.05, 0.9, 0.05])  # every step favours goal 1 over goal 0 by 18x
    for _ in range(200):
        b = update_log_belief(b, against, _uniform(), config)
    assert 1e-3 * (1 - 1e-12) <= np.exp(b[0]) < 1.1e-3  # held up by the floor alone
    steps = 0
    while int(np.argmax(b)) != 0:
        b = update_log_belief(b, np.log([0.9, 0.05, 0.05]), _uniform(), config)
        steps += 1
        assert steps <= 5, "the floored goal did not come back"
    # without the floor it would take ~200 steps to undo 200 steps of evidence
    assert steps <= 3


def test_zero_prior_with_a_floor_is_not_ruled_out_for_good() -> None:
    prior = prior_log_probs(GOALS3, {"x": 0.0, "y": 0.5, "z": 0.5})
    assert prior[0] == -np.inf
    config = BeliefConfig(forgetting=0.9, floor=0.01)
    b = initial_log_belief(prior, config)
    np.testing.assert_allclose(np.exp(b), [0.01, 0.495, 0.495], rtol=1e-12)
    for _ in range(20):
        b = update_log_belief(b, np.log([0.9, 0.05, 0.05]), prior, config)
    assert int(np.argmax(b)) == 0


# --- rows that are no evidence ---------------------------------------------------------------


@pytest.mark.parametrize(
    "bad_row",
    [
        [np.nan, -1.0, -2.0],
        [-np.inf, -np.inf, -np.inf],
        [np.inf, -1.0, -1.0],
        [np.nan, np.nan, np.nan],
    ],
)
def test_non_finite_likelihood_rows_leave_the_belief_unchanged(bad_row: list[float]) -> None:
    b = np.log([[0.2, 0.5, 0.3], [0.6, 0.2, 0.2]])
    lik = np.array([bad_row, np.log([0.9, 0.05, 0.05])])
    new = update_log_belief(b, lik, _uniform(), BeliefConfig())
    np.testing.assert_array_equal(new[0], b[0])  # untouched, not even forgotten
    assert not np.allclose(new[1], b[1])  # the other partner's row is updated
    assert np.isfinite(new).all()
    assert evidence_rows(lik).tolist() == [False, True]


def test_evidence_that_leaves_no_goal_possible_is_ignored_without_a_floor() -> None:
    b = np.array([-np.inf, 0.0, -np.inf])
    lik = np.array([0.0, -np.inf, 0.0])
    new = update_log_belief(b, lik, _uniform(), BeliefConfig(forgetting=1.0, floor=0.0))
    np.testing.assert_array_equal(new, b)


def test_partial_minus_inf_rows_are_evidence() -> None:
    lik = np.array([-np.inf, -1.0, -2.0])
    assert evidence_rows(lik)
    new = update_log_belief(_uniform(), lik, _uniform(), BAYES)
    assert new[0] == -np.inf and np.exp(new[1:]).sum() == pytest.approx(1.0)


# --- prior ------------------------------------------------------------------------------------


def test_prior_uniform_given_and_announced() -> None:
    np.testing.assert_allclose(np.exp(prior_log_probs(GOALS3)), [1 / 3] * 3)
    given = prior_log_probs(GOALS3, {"z": 0.25, "x": 0.75})
    np.testing.assert_allclose(np.exp(given), [0.75, 0.0, 0.25])
    announced = prior_log_probs(GOALS3, announced="y", announced_weight=0.8)
    np.testing.assert_allclose(np.exp(announced), [0.1, 0.8, 0.1])
    # the doubt spread by a given prior instead of uniformly
    both = prior_log_probs(
        GOALS3, {"x": 0.5, "y": 0.25, "z": 0.25}, announced="y", announced_weight=0.6
    )
    np.testing.assert_allclose(np.exp(both), [0.4 * 2 / 3, 0.6, 0.4 / 3])
    np.testing.assert_allclose(np.exp(prior_log_probs(("only",), announced="only")), [1.0])


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"prior": {"x": 0.5, "y": 0.6}}, "prior:"),
        ({"prior": {"x": 1.2, "y": -0.2}}, "prior[y]:"),
        ({"prior": {"x": -0.2, "y": 1.2}}, "prior[x]:"),
        ({"prior": {"w": 1.0}}, "prior[w]:"),
        ({"prior": {"x": float("nan"), "y": 1.0}}, "prior[x]:"),
        ({"prior": {}}, "prior:"),
        ({"announced": "w"}, "announced:"),
        ({"announced": "x", "announced_weight": 0.0}, "announced_weight:"),
        ({"announced": "x", "announced_weight": 1.5}, "announced_weight:"),
    ],
)
def test_prior_errors_name_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=r"^" + re.escape(field)):
        prior_log_probs(GOALS3, **kwargs)


# --- config -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("config", "field"),
    [
        (BeliefConfig(forgetting=1.5), "belief.forgetting"),
        (BeliefConfig(forgetting=0.0), "belief.forgetting"),
        (BeliefConfig(forgetting=float("nan")), "belief.forgetting"),
        (BeliefConfig(forgetting=True), "belief.forgetting"),
        (BeliefConfig(forgetting="0.9"), "belief.forgetting"),  # type: ignore[arg-type]
        (BeliefConfig(floor=-0.01), "belief.floor"),
        (BeliefConfig(floor=1 / 35), "belief.floor"),
        (BeliefConfig(floor=float("inf")), "belief.floor"),
        (BeliefConfig(temperature=0.0), "belief.temperature"),
        (BeliefConfig(temperature=-1.0), "belief.temperature"),
        (BeliefConfig(temperature=float("inf")), "belief.temperature"),
        (BeliefConfig(noise=-0.01), "belief.noise"),
        (BeliefConfig(noise=1.0), "belief.noise"),
        (BeliefConfig(noise=float("nan")), "belief.noise"),
        (BeliefConfig(noise=True), "belief.noise"),
        (BeliefConfig(noise="0.1"), "belief.noise"),  # type: ignore[arg-type]
    ],
)
def test_config_errors_name_the_field(config: BeliefConfig, field: str) -> None:
    with pytest.raises(ValueError, match=rf"^{re.escape(field)}: expected"):
        config.validate(35)
    with pytest.raises(ValueError, match=rf"^{re.escape(field)}:"):
        update_log_belief(_uniform(35), _uniform(35), _uniform(35), config)


def test_good_configs_pass() -> None:
    BeliefConfig().validate(35)
    BeliefConfig(forgetting=1, floor=0, temperature=0.02).validate(35)
    BeliefConfig(noise=0).validate(35)
    BeliefConfig(noise=0.999).validate(35)
    BeliefConfig(floor=0.49).validate(2)


def test_shape_errors_name_the_argument() -> None:
    with pytest.raises(ValueError, match=r"^log_lik_PG:"):
        update_log_belief(_uniform(), _uniform(4), _uniform(), BAYES)
    with pytest.raises(ValueError, match=r"^log_prior_PG:"):
        update_log_belief(_uniform(), _uniform(), _uniform(4), BAYES)
    with pytest.raises(ValueError, match=r"^actions_P:"):
        boltzmann_log_likelihoods(Q_3GOALS_1GA, np.array([2]), np.ones(3))
    with pytest.raises(ValueError, match=r"^actions_P:"):
        boltzmann_log_likelihoods(Q_3GOALS_1GA, np.array([0.0]), np.ones(3))
    with pytest.raises(ValueError, match=r"^alpha_G:"):
        boltzmann_log_likelihoods(Q_3GOALS_1GA, np.array([0]), np.array([1.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match=r"^q_PGA:"):
        boltzmann_log_likelihoods(Q_3GOALS_1GA[0], np.array([0]), np.ones(3))


# --- summaries --------------------------------------------------------------------------------


def test_top_goals_entropy_and_cross_entropy() -> None:
    b = np.log([0.2, 0.5, 0.2, 0.1])
    goals = ("a", "b", "c", "d")
    assert top_goals(b, goals, k=3) == [
        ("b", pytest.approx(0.5)),
        ("a", pytest.approx(0.2)),  # a tie: goal order
        ("c", pytest.approx(0.2)),
    ]
    assert belief_entropy(_uniform(4)) == pytest.approx(math.log(4))
    assert belief_entropy(np.array([0.0, -np.inf, -np.inf])) == 0.0
    expected = -(0.5 * math.log(0.5) + 2 * 0.2 * math.log(0.2) + 0.1 * math.log(0.1))
    assert belief_entropy(b) == pytest.approx(expected)
    assert belief_cross_entropy(b, 3) == pytest.approx(math.log(10))
    with pytest.raises(ValueError, match=r"^true_index:"):
        belief_cross_entropy(b, 4)


def test_blend_goal_probs_covers_the_mass_and_renormalises() -> None:
    goals = ("a", "b", "c", "d", "e")
    probs = [0.05, 0.6, 0.3, 0.04, 0.01]
    b = np.log(probs)
    # default: the whole belief, in the order of `goals` (exact, the same set at every step)
    whole = blend_goal_probs(b, goals)
    assert list(whole) == list(goals)
    assert list(whole.values()) == pytest.approx(probs, rel=1e-12)
    assert blend_goal_probs(b, goals, mass=1.0, max_goals=5) == whole
    assert blend_goal_probs(b, goals, mass=0.5) == {"b": 1.0}
    got = blend_goal_probs(b, goals, mass=0.9)  # 0.6 + 0.3 reaches 0.9
    assert list(got) == ["b", "c"]
    assert got["b"] == pytest.approx(0.6 / 0.9) and got["c"] == pytest.approx(0.3 / 0.9)
    got = blend_goal_probs(b, goals, mass=0.99, max_goals=3)  # the top 3, in goal order
    assert list(got) == ["a", "b", "c"] and math.fsum(got.values()) == pytest.approx(1.0, abs=1e-15)
    goals35 = [f"g{i}" for i in range(35)]
    assert len(blend_goal_probs(_uniform(35), goals35)) == 35
    assert len(blend_goal_probs(_uniform(35), goals35, mass=0.99, max_goals=8)) == 8
    # a goal of probability 0 (only without a floor) is left out
    assert list(blend_goal_probs(np.array([-LN2, -np.inf, -LN2]), GOALS3)) == ["x", "z"]
    with pytest.raises(ValueError, match=r"^mass:"):
        blend_goal_probs(b, goals, mass=0.0)
    with pytest.raises(ValueError, match=r"^max_goals:"):
        blend_goal_probs(b, goals, max_goals=0)
