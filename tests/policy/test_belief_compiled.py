"""`policy.belief_compiled`: the compiled belief update, views and likelihood table against the
numpy reference, within 1e-12 (absolute on log-probabilities and probabilities), on random,
peaked, flat, floored and extreme beliefs (the top goals and the kept goals exactly); they step
aside (None) where the numpy path masks."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from policy import belief_compiled as bc
from policy.belief import BeliefConfig, PreparedUpdate, belief_views, update_log_belief

pytestmark = pytest.mark.skipif(not bc.COMPILED, reason="built without a C compiler")
TOL = 1e-12


def same_views(got: list[bc.BeliefView], want: list[bc.BeliefView]) -> None:
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        assert a.blend_goals == b.blend_goals
        np.testing.assert_allclose(a.blend_probs, b.blend_probs, rtol=0, atol=TOL)
        assert [g for g, _ in a.top] == [g for g, _ in b.top]
        np.testing.assert_allclose([p for _, p in a.top], [p for _, p in b.top], rtol=0, atol=TOL)
        assert a.entropy == pytest.approx(b.entropy, rel=0, abs=TOL)


def both(call: Callable[[], Any], monkeypatch: pytest.MonkeyPatch) -> tuple[Any, Any]:
    """`call()` compiled, then with the numpy path."""
    compiled = call()
    with monkeypatch.context() as patch:
        patch.setattr(bc, "_EXTENSION", None)
        reference = call()
    return compiled, reference


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
def test_the_update_matches_numpy(
    kind: str, config: BeliefConfig, rows: int, goals: int, monkeypatch: pytest.MonkeyPatch
) -> None:
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
        got, want = both(lambda: update(log_b, lik), monkeypatch)  # noqa: B023
        np.testing.assert_allclose(got, want, rtol=TOL, atol=TOL)
        got, want = both(lambda: update_log_belief(log_b[0], lik[0], prior[0], config), monkeypatch)  # noqa: B023
        np.testing.assert_allclose(got, want, rtol=TOL, atol=TOL)


def test_non_finite_evidence_takes_the_numpy_path(monkeypatch: pytest.MonkeyPatch) -> None:
    prior = np.log(np.full((2, 5), 0.2))
    update = PreparedUpdate(prior, BeliefConfig())
    with np.errstate(divide="ignore"):
        lik = np.log(np.array([[0.1, 0.2, 0.3, 0.2, 0.2], [0.0, 0.5, 0.5, 0.0, 0.0]]))
    assert bc.compiled_update(prior, lik, None, 0.9, 1e-3) is None
    got, want = both(lambda: update(prior, lik), monkeypatch)
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("kind", ["random", "peaked", "flat", "ties"])
@pytest.mark.parametrize(
    ("rows", "goals", "k"), [(1, 35, 3), (4, 35, 3), (2, 1, 3), (3, 9, 9), (2, 200, 64)]
)
def test_the_views_match_numpy(
    kind: str, rows: int, goals: int, k: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    rng = np.random.default_rng(goals + k)
    names = [f"g{i}" for i in range(goals)]
    for _ in range(20):
        log_b = log_beliefs(rng, rows, goals, kind)
        assert bc.compiled_views(log_b, names, k) is not None
        got, want = both(lambda: belief_views(log_b, names, k), monkeypatch)  # noqa: B023
        same_views(got, want)


def test_a_zero_probability_takes_the_numpy_path(monkeypatch: pytest.MonkeyPatch) -> None:
    with np.errstate(divide="ignore"):
        log_b = np.log(np.array([[0.5, 0.5, 0.0], [0.2, 0.3, 0.5]]))
    assert bc.compiled_views(log_b, ["a", "b", "c"], 2) is None
    got, want = both(lambda: belief_views(log_b, ["a", "b", "c"], 2), monkeypatch)
    assert got == want


def test_bad_arguments_are_refused() -> None:
    from policy import _belief_row

    with pytest.raises(ValueError, match="log_belief"):
        _belief_row.update_rows(
            np.zeros((2, 3), np.float32), np.zeros((2, 3)), None, 1.0, 0.0, None
        )
    with pytest.raises(ValueError, match="lik, pull"):
        _belief_row.update_rows(np.zeros((2, 3)), np.zeros((1, 3)), None, 1.0, 0.0, None)
    with pytest.raises(ValueError, match="k: expected"):
        _belief_row.view_rows(np.zeros((2, 3)), 0)


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
    from policy import _belief_row

    q_RA, units = np.zeros((6, 5), np.float32), np.array([[0, 1, 2]], np.intp)
    with pytest.raises(ValueError, match="q_RA"):
        _belief_row.mix_goals(q_RA.astype(np.float64), units, [(1, 0, 0)], 1)
    with pytest.raises(ValueError, match="units_PG: expected"):
        _belief_row.mix_goals(q_RA, units.astype(np.int32), [(1, 0, 0)], 1)
    with pytest.raises(ValueError, match="outside"):
        _belief_row.mix_goals(q_RA, units, [(1, 0, 0)], 3)  # unit 2 needs rows 6..8
    with pytest.raises(ValueError, match="G numbers"):
        _belief_row.mix_goals(q_RA, units, [(1, 0)], 1)
    with pytest.raises(ValueError, match="one sequence per row"):
        _belief_row.mix_goals(q_RA, units, [(1, 0, 0), (1, 0, 0)], 1)
    with pytest.raises(TypeError):
        _belief_row.mix_goals(q_RA, units, [(1, "x", 0)], 1)


def test_the_goal_mix_steps_aside_for_other_q_layouts() -> None:
    """Float64 or strided Q-values are the numpy path's (None), never an error."""
    q_RA = np.ones((4, 5), np.float32)
    units, probs = np.array([[0, 1]], np.intp), [(0.5, 0.5)]
    assert bc.compiled_mix_goals(q_RA.astype(np.float64), units, probs, 1) is None
    assert bc.compiled_mix_goals(np.ones((5, 4), np.float32).T, units, probs, 1) is None
    assert bc.compiled_mix_goals(q_RA, units, probs, 1) is not None
