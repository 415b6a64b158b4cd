"""`policy.row_forward`: the compiled stack forward against the numpy reference and a float64
forward (within 1e-4), each row computed alone, the same bits at every vector width the CPU
has, non-finite values kept, bad arguments refused;
the numpy reference's one-member 2-D path against its stacked path."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from policy import row_forward as rf
from policy.row_forward import mean_views, numpy_mean_views, numpy_row_forward, row_forward

compiled = pytest.mark.skipif(not rf.COMPILED, reason="no compiled forward on this machine")
Layers = list[tuple[np.ndarray, np.ndarray]]


def stack(rng: np.random.Generator, sizes: tuple[int, ...], nets: int) -> Layers:
    """`nets` random MLPs of `sizes` as (R, in, out) weights and (R, 1, out) biases."""
    return [
        (
            (rng.standard_normal((nets, n_in, n_out)) / np.sqrt(n_in)).astype(np.float32),
            (0.1 * rng.standard_normal((nets, 1, n_out))).astype(np.float32),
        )
        for n_in, n_out in itertools.pairwise(sizes)
    ]


def float64_forward(
    x: np.ndarray, layers: Layers, start: int, members: int, act: str
) -> np.ndarray:
    h = x.astype(np.float64)
    for k, (w, b) in enumerate(layers):
        h = np.matmul(h, w[start : start + members].astype(np.float64)) + b[start : start + members]
        if k < len(layers) - 1:
            h = np.maximum(h, 0.0) if act == "relu" else np.tanh(h)
    return h


# widths around the vector blocks: 128 / 64 / 16 / 8 outputs per pass, 4-way sums in the tail
SIZES = [
    (8, 128, 128, 5),
    (3, 7, 9, 1),
    (17, 130, 200, 12),
    (5, 64, 16),
    (200, 8, 24, 6, 3),
    (4, 2),
    (5, 130, 7),  # a small last layer after an input count not a multiple of 4
]


@compiled
@pytest.mark.parametrize("sizes", SIZES)
@pytest.mark.parametrize("activation", ["relu", "tanh"])
# rows in blocks of 4, 2 and 1 (7 = 4 + 2 + 1; 5 = 4 + 1)
@pytest.mark.parametrize(
    ("x_members", "rows"), [(1, 1), (1, 3), (1, 7), ("all", 1), ("all", 2), ("all", 5)]
)
def test_compiled_matches_numpy_and_float64(
    sizes: tuple[int, ...], activation: str, x_members: object, rows: int
) -> None:
    rng = np.random.default_rng(sum(sizes) + rows)
    nets, start = 6, 2
    members = nets - start
    layers = stack(rng, sizes, nets)
    x = rng.standard_normal((members if x_members == "all" else 1, rows, sizes[0]))
    x = x.astype(np.float32)
    got = row_forward(x, layers, start, members, activation)
    numpy_got = numpy_row_forward(x, layers, start, members, activation)
    exact = float64_forward(x, layers, start, members, activation)
    assert got.dtype == np.float32 and got.shape == (members, rows, sizes[-1])
    assert numpy_got.shape == got.shape
    # float32 rounding of sums of ~width terms of unit scale: far below 1e-4 either way
    np.testing.assert_allclose(got, exact, rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(numpy_got, exact, rtol=1e-4, atol=1e-4)


@compiled
@pytest.mark.parametrize("sizes", SIZES)
@pytest.mark.parametrize("rows", [1, 4, 6])
def test_member_offsets_pick_the_right_networks(sizes: tuple[int, ...], rows: int) -> None:
    """Member m is network start + m: each alone gives its own row of the whole stack, bit for
    bit. The whole stack fetches each next member's weights ahead, a member alone fetches
    nothing: the prefetches change no result."""
    rng = np.random.default_rng(rows)
    layers = stack(rng, sizes, 7)
    x = rng.standard_normal((7, rows, sizes[0])).astype(np.float32)
    whole = row_forward(x, layers, 0, 7, "relu")
    for m in range(7):
        alone = row_forward(x[m : m + 1], layers, m, 1, "relu")
        np.testing.assert_array_equal(alone[0], whole[m])  # one member's loop, the same bits


@pytest.mark.skipif(len(rf.vector_widths()) < 2, reason="this CPU has one vector width")
@pytest.mark.parametrize("sizes", SIZES)
@pytest.mark.parametrize("activation", ["relu", "tanh"])
@pytest.mark.parametrize("rows", [1, 2, 3, 5, 9, 33])
def test_every_vector_width_gives_the_same_bits(
    sizes: tuple[int, ...], activation: str, rows: int
) -> None:
    """AVX-512's 16-float groups run each output's sum in the same order as AVX2's 8-float
    groups (policy/_row_forward_layer.h): an answer does not depend on the machine's vectors."""
    rng = np.random.default_rng(rows + len(sizes))
    layers = stack(rng, sizes, 5)
    x = rng.standard_normal((5, rows, sizes[0])).astype(np.float32)
    narrow = row_forward(x, layers, 0, 5, activation, lanes=8)
    for lanes in rf.vector_widths():
        np.testing.assert_array_equal(row_forward(x, layers, 0, 5, activation, lanes=lanes), narrow)
    np.testing.assert_array_equal(row_forward(x, layers, 0, 5, activation), narrow)  # the widest


@compiled
def test_a_vector_width_the_cpu_lacks_is_refused() -> None:
    rng = np.random.default_rng(4)
    layers = stack(rng, (4, 8, 3), 1)
    x = rng.standard_normal((1, 1, 4)).astype(np.float32)
    for lanes in (4, 12, 32) if 16 in rf.vector_widths() else (4, 16):
        with pytest.raises(ValueError, match="lanes: expected"):
            row_forward(x, layers, 0, 1, "relu", lanes=lanes)


def test_a_vector_width_is_refused_for_the_numpy_forward() -> None:
    """The numpy reference (an install without a C compiler, or asked for) has no width:
    asking for one is an error, not silently ignored."""
    rng = np.random.default_rng(5)
    layers = stack(rng, (4, 8, 3), 1)
    x = rng.standard_normal((1, 2, 4)).astype(np.float32)
    with pytest.raises(ValueError, match="lanes: expected 0"):
        row_forward(x, layers, 0, 1, "relu", lanes=8, numpy=True)
    np.testing.assert_array_equal(
        row_forward(x, layers, 0, 1, "relu", numpy=True),
        numpy_row_forward(x, layers, 0, 1, "relu"),
    )


def test_compiled_forward_is_built_here() -> None:
    """setup.py builds it wherever a C compiler is found, and this kind of machine has AVX2."""
    assert rf.COMPILED, "policy._row_forward missing (pip install -e . again) or no AVX2/FMA"


@compiled
def test_each_row_is_computed_alone() -> None:
    """A row's result does not depend on the rows that come with it (a session's likelihood
    table serves any subset of its partners: `goal_inference.ROWS_INDEPENDENT`)."""
    rng = np.random.default_rng(6)
    layers = stack(rng, (8, 128, 128, 5), 4)
    x = rng.standard_normal((1, 15, 8)).astype(np.float32)  # blocks of 8 (AVX-512), 4, 2, 1
    whole = row_forward(x, layers, 0, 4, "relu")
    for p in range(15):
        np.testing.assert_array_equal(
            row_forward(x[:, p : p + 1], layers, 0, 4, "relu")[:, 0], whole[:, p]
        )


def test_numpy_one_member_path_matches_its_stacked_path() -> None:
    rng = np.random.default_rng(7)
    layers = stack(rng, (8, 32, 5), 3)
    x = rng.standard_normal((1, 70, 8)).astype(np.float32)
    one = numpy_row_forward(x, layers, 1, 1, "tanh")
    exact = float64_forward(x, layers, 1, 1, "tanh")
    assert one.shape == (1, 70, 5)
    np.testing.assert_allclose(one, exact, rtol=1e-4, atol=1e-4)


@compiled
@pytest.mark.parametrize("activation", ["relu", "tanh"])
def test_non_finite_values_stay_non_finite(activation: str) -> None:
    """An overflow must reach the engine's isfinite check: relu keeps NaN (as numpy's maximum
    does), it does not turn it into 0."""
    rng = np.random.default_rng(1)
    layers = stack(rng, (4, 16, 3), 2)
    x = np.full((1, 2, 4), 3e38, dtype=np.float32)
    x[0, 1] = np.nan
    with np.errstate(all="ignore"):
        got = row_forward(x, layers, 0, 2, activation)
        want = numpy_row_forward(x, layers, 0, 2, activation)
    np.testing.assert_array_equal(np.isfinite(got), np.isfinite(want))
    assert not np.isfinite(got[:, 1]).any()


@compiled
def test_bad_arguments_are_refused_clearly() -> None:
    from policy import _row_forward

    rng = np.random.default_rng(2)
    layers = stack(rng, (4, 8, 3), 3)
    x = rng.standard_normal((1, 1, 4)).astype(np.float32)
    with pytest.raises(ValueError, match="x: expected a C-contiguous float32"):
        _row_forward.forward(x.astype(np.float64), layers, 0, 3, "relu")
    with pytest.raises(ValueError, match=r"layers\[0\]: expected weights \(R >= 4"):
        _row_forward.forward(x, layers, 1, 3, "relu")  # members 1..3 of a stack of 3
    with pytest.raises(ValueError, match=r"layers\[0\]"):
        _row_forward.forward(np.zeros((1, 1, 5), np.float32), layers, 0, 3, "relu")
    with pytest.raises(ValueError, match=r"layers\[1\]\[0\]"):
        bad = [layers[0], (np.asfortranarray(layers[1][0]), layers[1][1])]
        _row_forward.forward(x, bad, 0, 3, "relu")
    with pytest.raises(TypeError, match=r"layers\[0\]"):
        _row_forward.forward(x, [layers[0][0]], 0, 3, "relu")  # type: ignore[list-item]
    with pytest.raises(ValueError, match="activation"):
        _row_forward.forward(x, layers, 0, 3, "gelu")
    with pytest.raises(ValueError, match="x: expected"):
        _row_forward.forward(np.zeros((2, 1, 4), np.float32), layers, 0, 3, "relu")


@compiled
def test_threads_share_it_safely() -> None:
    """The GIL is released while it runs: threads calling it at once get their own answers."""
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(3)
    layers = stack(rng, (8, 128, 128, 5), 35)
    xs = [rng.standard_normal((35, 1, 8)).astype(np.float32) for _ in range(8)]
    want = [row_forward(x, layers, 0, 35, "relu") for x in xs]
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda x: row_forward(x, layers, 0, 35, "relu"), xs * 4))
    for k, result in enumerate(got):
        np.testing.assert_array_equal(result, want[k % len(xs)])


@pytest.mark.parametrize(("rows", "views"), [(1, 1), (4, 4), (12, 3), (40, 5)])
def test_mean_views_equals_the_reference(rows: int, views: int) -> None:
    """The same float32 sums in the same order: the same values, not merely close ones."""
    q = np.random.default_rng(rows).standard_normal((rows, 5)).astype(np.float32) * 1e3
    got = mean_views(q, views)
    assert got.dtype == np.float64 and got.shape == (rows // views, 5)
    np.testing.assert_array_equal(got, numpy_mean_views(q, views))
    overflowing = np.full((2, 5), np.finfo(np.float32).max, np.float32)
    assert np.isinf(mean_views(overflowing, 2)).all()  # the float32 sum overflows, as numpy's


def test_mean_views_refuses_a_block_that_does_not_divide_the_rows() -> None:
    if rf._extension is None:
        pytest.skip("policy._row_forward not built")
    with pytest.raises(ValueError, match="views: expected a divisor"):
        mean_views(np.zeros((5, 3), np.float32), 2)
