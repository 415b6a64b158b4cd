"""`policy.belief_compiled` (numba, `policy.belief_kernel`): the compiled belief update, views,
likelihood table and goal mix against the numpy reference (`policy.belief.reference_update`,
`policy.belief_views.reference_views`, the engine's numpy lines), within 1e-12 (absolute on
log-probabilities and probabilities), on random, peaked, flat, floored and extreme beliefs (the
top goals and the kept goals exactly), over 10,000 random rows each for the update and the
views; they step aside (None) where the numpy path masks."""

from __future__ import annotations

import numpy as np
import pytest

from policy import belief_compiled as bc
from policy import belief_kernel
from policy.belief import (
    BeliefConfig,
    PreparedUpdate,
    _forgetting_pull,
    belief_views,
    reference_update,
    update_log_belief,
)
from policy.belief_views import reference_views

TOL = 1e-12


def same_views(got: list[bc.BeliefView], want: list[bc.BeliefView]) -> None:
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        assert a.blend_goals == b.blend_goals
        np.testing.assert_allclose(a.blend_probs, b.blend_probs, rtol=0, atol=TOL)
        assert [g for g, _ in a.top] == [g for g, _ in b.top]
        np.testing.assert_allclose([p for _, p in a.top], [p for _, p in b.top], rtol=0, atol=TOL)
        assert a.entropy == pytest.approx(b.entropy, rel=0, abs=TOL)


def log_beliefs(rng: np.random.Generator, rows: int, goals: int, kind: str) -> np.ndarray:
    if kind == "random":
        x = rng.standard_normal((rows, goals)) * 3
    elif kind == "peaked":
        x = rng.standard_normal((rows, goals)) * 40
    elif kind == "flat":
        x = np.zeros((rows, goals)) + rng.standard_normal((rows, goals)) * 1e-12
    else:  # ties
        x = np.round(rng.standard_normal((rows, goals)))
    return (
        x
        - np.log(np.exp(x - x.max(1, keepdims=True)).sum(1, keepdims=True))
        - x.max(1, keepdims=True)
    )


@pytest.mark.parametrize("kind", ["random", "peaked", "flat", "ties"])
@pytest.mark.parametrize(
    "config",
    [
        BeliefConfig(),
        BeliefConfig(forgetting=1.0, floor=0.0),
        BeliefConfig(forgetting=0.5, floor=0.01),
    ],
)
@pytest.mark.parametrize(("rows", "goals"), [(1, 35), (4, 35), (3, 1), (2, 7), (5, 200)])
def test_the_update_matches_numpy(kind: str, config: BeliefConfig, rows: int, goals: int) -> None:
    if config.floor * goals >= 1:
        config = BeliefConfig(forgetting=config.forgetting, floor=0.0)
    rng = np.random.default_rng(rows * 1000 + goals)
    for _ in range(20):
        prior = log_beliefs(rng, rows, goals, "random")
        log_b = log_beliefs(rng, rows, goals, kind)
        lik = -np.abs(rng.standard_normal((rows, goals))) * rng.choice([0.01, 1, 300])
        update = PreparedUpdate(prior, config)
        # the compiled path did run (the comparison below is not numpy against itself)
        assert bc.compiled_update(log_b, lik, None, config.forgetting, config.floor) is not None
        lam, eps = config.forgetting, config.floor
        want = reference_update(log_b, lik, update._pull_PG, lam, eps)
        np.testing.assert_allclose(update(log_b, lik), want, rtol=TOL, atol=TOL)
        got = update_log_belief(log_b[0], lik[0], prior[0], config)
        pull = _forgetting_pull(prior[0], lam, eps)
        want = reference_update(log_b[0], lik[0], pull, lam, eps)
        np.testing.assert_allclose(got, want, rtol=TOL, atol=TOL)


@pytest.mark.parametrize("floor", [0.0, 1e-3])
def test_ten_thousand_random_updates_match_numpy(floor: float) -> None:
    """10,000 random rows of 35 goals (a session's partner beliefs), in batches of 1 to 8
    rows, with and without the prior's pull: the compiled update within 1e-12 of numpy's."""
    rng = np.random.default_rng(10_000 + int(floor * 1e3))
    done, worst = 0, 0.0
    while done < 10_000:
        rows = int(rng.integers(1, 9))
        log_b = log_beliefs(rng, rows, 35, str(rng.choice(["random", "peaked", "flat", "ties"])))
        lik = -np.abs(rng.standard_normal((rows, 35))) * rng.choice([0.01, 1, 300])
        pull = None if rng.random() < 0.3 else 0.1 * log_beliefs(rng, rows, 35, "random")
        got = bc.compiled_update(log_b, lik, pull, 0.9, floor)
        assert got is not None
        want = reference_update(log_b, lik, pull, 0.9, floor)
        worst = max(worst, float(np.abs(got - want).max()))
        done += rows
    assert worst <= TOL


def test_non_finite_evidence_takes_the_numpy_path() -> None:
    prior = np.log(np.full((2, 5), 0.2))
    update = PreparedUpdate(prior, BeliefConfig())
    with np.errstate(divide="ignore"):
        lik = np.log(np.array([[0.1, 0.2, 0.3, 0.2, 0.2], [0.0, 0.5, 0.5, 0.0, 0.0]]))
    assert bc.compiled_update(prior, lik, None, 0.9, 1e-3) is None
    want = reference_update(prior, lik, update._pull_PG, update.forgetting, update.floor)
    np.testing.assert_array_equal(update(prior, lik), want)


@pytest.mark.parametrize("kind", ["random", "peaked", "flat", "ties"])
@pytest.mark.parametrize(
    ("rows", "goals", "k"), [(1, 35, 3), (4, 35, 3), (2, 1, 3), (3, 9, 9), (2, 200, 64)]
)
def test_the_views_match_numpy(kind: str, rows: int, goals: int, k: int) -> None:
    rng = np.random.default_rng(goals + k)
    names = [f"g{i}" for i in range(goals)]
    for _ in range(20):
        log_b = log_beliefs(rng, rows, goals, kind)
        got = bc.compiled_views(log_b, names, k)
        assert got is not None
        same_views(got, reference_views(log_b, names, k, 1.0, None))
        same_views(belief_views(log_b, names, k), got)


def test_ten_thousand_random_views_match_numpy() -> None:
    """10,000 random belief rows of 35 goals, in batches of 1 to 8."""
    rng = np.random.default_rng(20_000)
    names = [f"g{i}" for i in range(35)]
    done, worst = 0, 0.0
    while done < 10_000:
        rows = int(rng.integers(1, 9))
        log_b = log_beliefs(rng, rows, 35, str(rng.choice(["random", "peaked", "flat", "ties"])))
        got = bc.compiled_views(log_b, names, 3)
        assert got is not None
        want = reference_views(log_b, names, 3, 1.0, None)
        assert [v.top[0][0] for v in got] == [v.top[0][0] for v in want]
        for field in ("blend_probs", "entropy"):
            gap = np.subtract([getattr(v, field) for v in got], [getattr(v, field) for v in want])
            worst = max(worst, float(np.abs(gap).max()))
        done += rows
    assert worst <= TOL


def test_a_zero_probability_takes_the_numpy_path() -> None:
    with np.errstate(divide="ignore"):
        log_b = np.log(np.array([[0.5, 0.5, 0.0], [0.2, 0.3, 0.5]]))
    for rows in (log_b, log_b[::-1].copy()):  # in the first row and after a usable one
        assert bc.compiled_views(rows, ["a", "b", "c"], 2) is None
        want = reference_views(rows, ["a", "b", "c"], 2, 1.0, None)
        assert belief_views(rows, ["a", "b", "c"], 2) == want


def test_bad_arguments_are_refused() -> None:
    """The kernels check what they index (the wrappers hand them the right types)."""
    update, zeros = belief_kernel.update_rows, np.zeros((2, 3))
    with pytest.raises(TypeError):
        update(np.zeros((2, 3), np.float32), zeros, zeros, False, 1.0, 0.0, False, 0.0)
    with pytest.raises(ValueError, match="lik, pull"):
        update(zeros, np.zeros((1, 3)), zeros, False, 1.0, 0.0, False, 0.0)
    with pytest.raises(ValueError, match="lik, pull"):
        update(zeros, zeros, np.zeros((2, 4)), True, 1.0, 0.0, False, 0.0)
    with pytest.raises(ValueError, match="k: expected"):
        belief_kernel.view_rows(zeros, 0)


@pytest.mark.parametrize(
    ("goals", "partners", "actions"), [(35, 1, 5), (35, 4, 5), (3, 2, 1), (7, 3, 9)]
)
@pytest.mark.parametrize("alpha_kind", ["per goal", "scalar", "tiny"])
def test_the_log_softmax_table_matches_the_engines_numpy(
    goals: int, partners: int, actions: int, alpha_kind: str
) -> None:
    """`compiled_log_softmax` against the engine's numpy lines (`goal_inference._scaled`, then
    z - log_norm), which the tests of the goal likelihoods hold to `boltzmann_log_likelihoods`."""
    from services.engine.goal_inference import _scaled

    rng = np.random.default_rng(goals * partners + actions)
    for _ in range(20):
        q = (rng.standard_normal((goals, partners, actions)) * rng.choice([0.01, 1, 50])).astype(
            np.float32
        )
        if alpha_kind == "per goal":
            alpha: np.ndarray | float = rng.uniform(0.005, 2, goals)[:, None, None]
        else:
            alpha = 1e-300 if alpha_kind == "tiny" else 0.02
        with np.errstate(over="ignore"):
            z, log_norm = _scaled(q, alpha, alpha_kind == "tiny")
        want = z - log_norm[:, :, None]
        got = bc.compiled_log_softmax(q, alpha)
        assert got is not None
        np.testing.assert_array_equal(np.isfinite(got), np.isfinite(want))
        finite = np.isfinite(want)
        np.testing.assert_allclose(got[finite], want[finite], rtol=TOL, atol=TOL)


@pytest.mark.parametrize(
    ("partners", "goals", "batch"), [(4, 35, 1), (1, 35, 1), (3, 4, 3), (2, 7, 5), (1, 1, 2)]
)
def test_the_goal_mix_matches_numpys_einsum(partners: int, goals: int, batch: int) -> None:
    """`compiled_mix_goals` against the einsum `_impact_q` falls back to: out[b, p] = sum over g
    of probs[p][g] * q[units[p, g] * B + b], on units in any order (a goal's network may
    serve partners in another order than the catalogue's)."""
    rng = np.random.default_rng(partners * goals * batch)
    for _ in range(20):
        n_units = partners * goals + int(rng.integers(0, 3))
        q_RA = (rng.standard_normal((n_units * batch, 5)) * rng.choice([0.01, 1, 1e4])).astype(
            np.float32
        )
        units_PG = rng.permutation(n_units)[: partners * goals].reshape(partners, goals)
        probs_PG = rng.dirichlet(np.ones(goals), partners)
        rows_PGB = units_PG[:, :, None] * batch + np.arange(batch)
        want = np.einsum("pg,pgba->bpa", probs_PG, q_RA[rows_PGB].astype(np.float64))
        got = bc.compiled_mix_goals(q_RA, units_PG.astype(np.intp), probs_PG.tolist(), batch)
        assert got is not None and got.shape == (batch, partners, 5)
        np.testing.assert_allclose(got, want, rtol=TOL, atol=TOL * np.abs(want).max())


def test_the_goal_mix_carries_non_finite_q_values() -> None:
    """An overflowed (inf) Q-value stays non-finite in the mix: the engine's overflow check
    after it must see it."""
    q_RA = np.ones((4, 5), np.float32)
    q_RA[2, 1] = np.inf
    got = bc.compiled_mix_goals(q_RA, np.array([[0, 2], [1, 3]], np.intp), [(0.5, 0.5)] * 2, 1)
    assert got is not None
    np.testing.assert_array_equal(
        np.isfinite(got[0]), [[True, False, True, True, True], [True] * 5]
    )


def test_bad_goal_mix_arguments_are_refused() -> None:
    q_RA, units = np.zeros((6, 5), np.float32), np.array([[0, 1, 2]], np.intp)
    with pytest.raises(ValueError, match="outside"):
        bc.compiled_mix_goals(q_RA, units, [(1, 0, 0)], 3)  # unit 2 needs rows 6..8
    with pytest.raises(ValueError, match="outside"):
        bc.compiled_mix_goals(q_RA, -units, [(1, 0, 0)], 1)
    with pytest.raises(ValueError):
        bc.compiled_mix_goals(q_RA, units, [(1, 0)], 1)  # G numbers per partner
    with pytest.raises(ValueError):
        bc.compiled_mix_goals(q_RA, units, [(1, 0, 0), (1, 0, 0)], 1)  # one row per partner
    with pytest.raises(ValueError):
        bc.compiled_mix_goals(q_RA, units, [(1, "x", 0)], 1)  # type: ignore[list-item]
    with pytest.raises(ValueError, match="batch"):
        belief_kernel.mix_goals(q_RA, units.astype(np.int64), np.ones((1, 3)), 0)


def test_the_goal_mix_steps_aside_for_other_q_layouts() -> None:
    """Float64 or strided Q-values are the numpy path's (None), never an error."""
    q_RA = np.ones((4, 5), np.float32)
    units, probs = np.array([[0, 1]], np.intp), [(0.5, 0.5)]
    assert bc.compiled_mix_goals(q_RA.astype(np.float64), units, probs, 1) is None
    assert bc.compiled_mix_goals(np.ones((5, 4), np.float32).T, units, probs, 1) is None
    assert bc.compiled_mix_goals(q_RA, units, probs, 1) is not None
