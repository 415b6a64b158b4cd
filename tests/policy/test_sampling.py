"""`policy.sampling`: the compiled sampler (`policy.blend_kernel.sample_rows`) gives the numpy
reference's actions exactly, never draws an action of probability 0, and follows the inverse
CDF by hand."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from policy.sampling import numpy_sample_rows, sample_actions, sample_rows


def test_inverse_cdf_by_hand() -> None:
    probs = np.array([[0.2, 0.3, 0.5]] * 4 + [[0.0, 1.0, 0.0]])
    u = np.array([0.1, 0.25, 0.5, 0.99, 0.0])
    # cdf 0.2, 0.5, 1.0: u = 0.5 does not exceed 0.5, so action 2; a p = 0 action is never drawn
    for sample in (sample_rows, numpy_sample_rows):
        actions, greedy = sample(probs, u)
        assert actions.tolist() == [0, 1, 2, 2, 1]
        assert greedy.tolist() == [2, 2, 2, 2, 1]
        assert actions.dtype == greedy.dtype == np.int64


@settings(max_examples=200, deadline=None)
@given(
    weights=st.lists(st.sampled_from([0.0, 0.0, 1e-9, 0.1, 1.0, 3.0]), min_size=1, max_size=6),
    seed=st.integers(0, 2**32),
)
def test_never_an_action_of_probability_zero(weights: list[float], seed: int) -> None:
    weights[seed % len(weights)] += 0.5  # at least one positive entry
    probs_BA = np.tile(np.array(weights) / sum(weights), (64, 1))
    actions = sample_actions(probs_BA, np.random.default_rng(seed).random(64))
    assert actions.shape == (64,)
    assert (probs_BA[0][actions] > 0).all()


@settings(max_examples=200, deadline=None)
@given(
    rows=st.integers(1, 40),
    n_actions=st.integers(1, 7),
    seed=st.integers(0, 2**32),
    ties=st.booleans(),
)
def test_compiled_equals_the_reference(rows: int, n_actions: int, seed: int, ties: bool) -> None:
    rng = np.random.default_rng(seed)
    probs = rng.random((rows, n_actions)) * (rng.random((rows, n_actions)) > 0.3)
    if ties:  # equal probabilities: the first most probable is the greedy action
        probs = np.round(probs, 1)
    probs[:, 0] += 1e-3  # every row has mass
    probs /= probs.sum(axis=1, keepdims=True)
    u = rng.random(rows)
    u[::5] = 0.0  # the lowest uniform, and thresholds on a cumulative sum
    got, expected = sample_rows(probs, u), numpy_sample_rows(probs, u)
    assert got[0].tolist() == expected[0].tolist()
    assert got[1].tolist() == expected[1].tolist()


def test_bad_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="shapes"):
        sample_rows(np.ones((3, 2)), np.ones(2))
    with pytest.raises(ValueError, match="shapes"):
        sample_rows(np.ones((3, 0)), np.ones(3))
