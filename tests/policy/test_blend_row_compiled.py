"""policy._blend_row (the compiled row blend) against policy.blend_fast's Python reference:
the same bits on every field, for random and ill-conditioned rows, every method, both
normalisations; errors for inputs that are not numbers; the Python fallback."""

from __future__ import annotations

import importlib
import os
import subprocess
import sys

import numpy as np
import pytest

blend_fast = importlib.import_module("policy.blend_fast")
FIELDS = ("q_A", "probs_A", "task_entropy", "task_weight", "partner_weights_P")


def _same_bits(a, b) -> bool:
    for field in FIELDS:
        x = np.atleast_1d(np.asarray(getattr(a, field), dtype=np.float64))
        y = np.atleast_1d(np.asarray(getattr(b, field), dtype=np.float64))
        if x.shape != y.shape or x.tobytes() != y.tobytes():  # tobytes: -0.0 != 0.0, NaN == NaN
            return False
    return True


def _rows(seed: int, count: int):
    """Rows shaped as tests/policy/test_policy_blend_fast.py's hypothesis cases: copies (Σw =
    0), near copies (JS distances of rounding), flat and nearly flat task vectors, magnitudes
    from 1e-300 to 1e300, masks, temperatures from 1e-300 to 1e6, 1-12 actions, 0-8 slots."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        n, slots = int(rng.integers(1, 13)), int(rng.integers(0, 9))
        scale = 10.0 ** rng.choice([-300, -12, 0, 0, 3, 300])
        q_task = rng.uniform(-10, 10, n) * scale
        q_impact = rng.uniform(-10, 10, (slots, n)) * scale
        shape = rng.integers(0, 5)
        if shape == 1:
            q_impact[:] = q_task
        elif shape == 2:
            q_impact[:] = (
                q_task * (1 + rng.choice([1e-13, 1e-11, 1e-9]) * np.arange(1, slots + 1))[:, None]
            )
        elif shape == 3:
            q_task[:] = q_task[0]
        elif shape == 4:
            q_task[:] = 1.0 + 1e-11 * q_task / (np.abs(q_task).max() or 1.0)
        mask = (rng.random(slots) < 0.7).tolist() if rng.random() < 0.5 else None
        alpha = float(rng.choice([1e-300, 1e-9, 0.02, 1.0, 1e6]))
        yield q_task.tolist(), q_impact.tolist(), alpha, mask


needs_compiled = pytest.mark.skipif(
    blend_fast._compiled is None, reason="policy._blend_row was not built (no C compiler)"
)


def test_the_compiled_blend_is_built_here() -> None:
    """setup.py builds it wherever a C compiler is found (CI has one); without it every row
    takes the Python reference, ~10x slower, so a silently failed build is caught here."""
    assert blend_fast._compiled is not None, "policy._blend_row missing: pip install -e . again"


@needs_compiled
@pytest.mark.parametrize("method", ["sl", "nail", "aail"])
@pytest.mark.parametrize("normalise", [True, False])
def test_compiled_rows_have_the_python_rows_bits(method: str, normalise: bool) -> None:
    for q_task, q_impact, alpha, mask in _rows(seed=len(method) + normalise, count=3000):
        compiled = blend_fast._compiled(method, q_task, q_impact, alpha, mask, normalise)
        python = blend_fast.blend_row_python(method, q_task, q_impact, alpha, mask, normalise)
        assert isinstance(compiled, blend_fast.RowBlend)
        assert _same_bits(compiled, python), (method, normalise, q_task, q_impact, alpha, mask)


@needs_compiled
def test_underflowed_mixture_and_huge_values() -> None:
    """The JS distance's irregular branch (m underflows to 0: a ratio of inf) and Q near the
    float64 limit go through the same steps."""
    cases = [
        ([0.0, -745.13], [[0.0, -1e6]], 1.0),
        ([1e300, -1e300, 0.0], [[-1e300, 1e300, 0.0]], 1e-300),
        ([5.0], [[2.0]], 1e-9),
        ([0.0, 1.0, 2.0], [[7.0, 7.0, 7.0]], 1.0),
    ]
    for q_task, q_impact, alpha in cases:
        for normalise in (True, False):
            compiled = blend_fast._compiled("aail", q_task, q_impact, alpha, None, normalise)
            python = blend_fast.blend_row_python("aail", q_task, q_impact, alpha, None, normalise)
            assert _same_bits(compiled, python), (q_task, q_impact, alpha)


@needs_compiled
@pytest.mark.parametrize("n_actions", [129, 300])
def test_many_actions_take_the_pairwise_sums(n_actions: int) -> None:
    """Above 128 terms numpy's pairwise sum splits in halves (and the entropy's terms need
    their own buffer): the same bits there too."""
    rng = np.random.default_rng(n_actions)
    for slots in (0, 1, 3):
        q_task, q_impact = rng.normal(size=n_actions) * 3, rng.normal(size=(slots, n_actions)) * 3
        for method in ("sl", "nail", "aail"):
            args = (method, q_task.tolist(), q_impact.tolist(), 0.5, None, True)
            assert _same_bits(blend_fast._compiled(*args), blend_fast.blend_row_python(*args))


@needs_compiled
def test_bad_inputs_raise_instead_of_crashing() -> None:
    with pytest.raises(ValueError, match="method"):
        blend_fast._compiled("xail", [1.0], [], 1.0, None, True)
    with pytest.raises(TypeError):
        blend_fast._compiled("aail", ["a", 1.0], [], 1.0, None, True)
    with pytest.raises(ValueError, match="q_impact_PA"):
        blend_fast._compiled("aail", [1.0, 2.0], [[1.0]], 1.0, None, True)
    with pytest.raises(ValueError, match="q_task_A"):
        blend_fast._compiled("aail", [], [], 1.0, None, True)


def test_blend_row_falls_back_to_python(monkeypatch) -> None:
    """COMPILED False (no extension, or COEXIST_PYTHON_BLEND=1): the reference runs."""
    monkeypatch.setattr(blend_fast, "COMPILED", False)
    calls: list[str] = []
    reference = blend_fast.blend_row_python

    def spy(*args):
        calls.append(args[0])
        return reference(*args)

    monkeypatch.setattr(blend_fast, "blend_row_python", spy)
    row = blend_fast.blend_row("aail", [0.0, 1.0, 3.0], [[2.0, 0.0, 1.0]], 0.5)
    assert calls == ["aail"] and row.partner_weights_P == [1.0]


def _batches(seed: int, count: int):
    """Batches of 0-20 rows built from `_rows`' shapes, per-row temperatures and masks."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        n_rows, n, slots = (
            int(rng.integers(0, 21)),
            int(rng.integers(1, 13)),
            int(rng.integers(0, 9)),
        )
        scale = 10.0 ** rng.choice([-300, -12, 0, 0, 3, 300])
        q_task = rng.uniform(-10, 10, (n_rows, n)) * scale
        q_impact = rng.uniform(-10, 10, (n_rows, slots, n)) * scale
        shape = rng.integers(0, 4)
        if shape == 1:
            q_impact[:] = q_task[:, None, :]
        elif shape == 2:
            q_impact[:] = q_task[:, None, :] * (1 + 1e-11 * np.arange(1, slots + 1))[:, None]
        elif shape == 3:
            q_task[:] = q_task[:, :1]
        mask = rng.random((n_rows, slots)) < 0.7
        alpha = rng.choice([1e-300, 1e-9, 0.02, 1.0, 1e6], size=n_rows)
        yield q_task, q_impact, alpha, mask


@needs_compiled
@pytest.mark.parametrize("method", ["sl", "nail", "aail"])
@pytest.mark.parametrize("normalise", [True, False])
def test_blend_of_a_batch_has_the_vectorised_bits(method: str, normalise: bool) -> None:
    """`policy.blend.blend` on the compiled batch against `blend_vectorised`, the reference
    (each ufunc is called once per batch: an element's result must not depend on the rest)."""
    blend_module = importlib.import_module("policy.blend")
    if not blend_fast.COMPILED:
        pytest.skip("COEXIST_PYTHON_BLEND=1: blend takes the Python paths")
    for q_task, q_impact, alpha, mask in _batches(seed=len(method) + 3 * normalise, count=400):
        fast = blend_module.blend(method, q_task, q_impact, alpha, mask, normalise=normalise)
        with np.errstate(all="ignore"):
            reference = blend_module.blend_vectorised(
                method, q_task, q_impact, alpha, mask, normalise=normalise
            )
        for field in ("q_BA", "probs_BA", "task_entropy_B", "task_weight_B", "partner_weights_BP"):
            got, want = getattr(fast, field), np.asarray(getattr(reference, field), np.float64)
            assert got.shape == want.shape and got.tobytes() == want.tobytes(), (method, field)


@needs_compiled
def test_batch_shapes_are_checked() -> None:
    rows = importlib.import_module("policy._blend_row").blend_rows
    q_task, q_impact = np.zeros((2, 3)), np.zeros((2, 1, 3))
    alpha, mask = np.ones(2), np.ones((2, 1), bool)
    with pytest.raises(ValueError, match="shapes"):
        rows("aail", q_task, np.zeros((2, 1, 4)), alpha, mask, True)
    with pytest.raises(ValueError, match="shapes"):
        rows("aail", q_task, q_impact, np.ones(3), mask, True)
    with pytest.raises(ValueError, match="q_task_BA"):
        rows("aail", np.zeros(3), q_impact, alpha, mask, True)


@needs_compiled
def test_the_environment_variable_forces_python() -> None:
    code = "from policy import blend_fast; print(blend_fast.COMPILED)"
    for value, expected in (("1", "False"), ("0", "True"), ("", "True")):
        env = {**os.environ, "COEXIST_PYTHON_BLEND": value}
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        assert out.stdout.strip() == expected, (value, out.stderr)
