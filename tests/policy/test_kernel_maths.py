"""`policy.kernel_maths`' exp and log against numpy's, over the whole range of doubles and at
the edges, both called one value at a time and in a loop LLVM vectorises."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from policy.kernel_maths import EXP_OVERFLOW, SMALLEST_NORMAL, exp, log

SMALLEST_SUBNORMAL = 5e-324


@njit(error_model="numpy")
def _exp_loop(x, out):
    for i in range(x.size):
        out[i] = exp(x[i])


@njit(error_model="numpy")
def _log_loop(x, out):
    for i in range(x.size):
        out[i] = log(x[i])


@njit(error_model="numpy")
def _exp_one(x):
    return exp(x)


@njit(error_model="numpy")
def _log_one(x):
    return log(x)


def _exp(x: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    _exp_loop(x, out)
    return out


def _log(x: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    _log_loop(x, out)
    return out


def _ulps(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    return np.abs(got - want) / np.spacing(np.abs(want))


def test_exp_is_within_two_ulp_of_numpys_wherever_the_result_is_normal() -> None:
    rng = np.random.default_rng(0)
    x = np.concatenate(
        [
            rng.uniform(-708.39, 709.78, 200_000),
            rng.uniform(-40.0, 0.0, 100_000),  # the blend's arguments: (q - max q) / alpha
            rng.uniform(-1e-3, 1e-3, 10_000),
        ]
    )
    want = np.exp(x)
    normal = want >= SMALLEST_NORMAL
    assert normal.sum() > 300_000
    assert _ulps(_exp(x)[normal], want[normal]).max() <= 2


def test_exp_rounds_to_the_subnormal_numbers_numpy_gives() -> None:
    """Below the normal range the result is one rounding of the series: numpy's number or
    the next subnormal; never 0 where numpy's is not (the blend's JS distances tell 0 from a
    subnormal probability)."""
    x = np.random.default_rng(1).uniform(-746.0, -708.4, 100_000)
    got, want = _exp(x), np.exp(x)
    assert np.abs(got - want).max() <= SMALLEST_SUBNORMAL
    assert np.array_equal(got == 0, want == 0)


def test_exp_at_its_edges() -> None:
    with np.errstate(over="ignore"):
        x = np.array([0.0, -0.0, 1.0, -1.0, EXP_OVERFLOW, 709.79, 1e6, -746.0, -1e6])
        want = np.exp(x)
    x = np.append(x, [np.inf, -np.inf, np.nan])
    want = np.append(want, [np.inf, 0.0, np.nan])
    _check_edges(_exp, _exp_one, x, want, ulps=2)


def test_log_is_within_four_ulp_of_numpys_for_every_positive_double() -> None:
    rng = np.random.default_rng(2)
    x = np.concatenate(
        [
            rng.uniform(0.0, 3.0, 100_000),  # the blend's ratios x / m lie in (0, 2]
            np.exp(rng.uniform(-744.0, 709.0, 100_000)),  # every binade, subnormals included
            1.0 + rng.uniform(-1e-9, 1e-9, 10_000),  # near a copy: x / m near 1
        ]
    )
    x = x[(x > 0) & (x != 1.0)]
    got, want = _log(x), np.log(x)
    assert np.count_nonzero(x < SMALLEST_NORMAL) > 100
    assert _ulps(got, want).max() <= 4


def test_log_at_its_edges() -> None:
    powers = [1.0, 2.0, 0.5, np.sqrt(2.0), np.nextafter(np.sqrt(2.0), 2.0)]
    extremes = [SMALLEST_SUBNORMAL, SMALLEST_NORMAL, np.finfo(float).max]
    x = np.array([*powers, *extremes, 0.0, -0.0, np.inf, -1.0, -np.inf, np.nan])
    with np.errstate(divide="ignore", invalid="ignore"):
        want = np.log(x)
    _check_edges(_log, _log_one, x, want, ulps=4)


def _check_edges(block, one, x: np.ndarray, want: np.ndarray, ulps: int) -> None:
    """`block(x)` within `ulps` of `want` where that is finite and not 0, exactly `want`
    elsewhere (0, infinities, NaN), and `one(value)` the same bits as `block` for every value."""
    got = block(x)
    finite = np.isfinite(want) & (want != 0)
    assert _ulps(got[finite], want[finite]).max() <= ulps
    assert np.array_equal(got[~finite], want[~finite], equal_nan=True)
    for value in x:  # one value at a time, not vectorised
        assert np.array_equal(one(value), block(np.array([value]))[0], equal_nan=True)


@pytest.mark.parametrize("function", [_exp, _log])
def test_a_value_in_a_block_has_the_bits_it_has_alone(function: object) -> None:
    """The blend vectorises these over blocks and the tail of a block runs one value at a time:
    both must give the same bits, or a row's answer would depend on where its values fell."""
    x = np.random.default_rng(3).uniform(-5.0, 5.0, 1_001)
    x = np.abs(x) if function is _log else x
    single = _exp_one if function is _exp else _log_one
    block = function(x)  # type: ignore[operator]
    assert np.array_equal(block, np.array([single(value) for value in x]))
