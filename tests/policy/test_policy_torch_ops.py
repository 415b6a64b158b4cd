"""policy.torch_ops agrees with policy.maths, differentiates correctly and samples fairly."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from policy.maths import boltzmann, soft_value
from policy.torch_ops import boltzmann_t, sample_boltzmann_t, soft_value_t


@pytest.mark.parametrize("alpha", [1e-9, 1e-3, 0.3, 1.0, 50.0])
def test_torch_matches_numpy(alpha: float) -> None:
    rng = np.random.default_rng(0)
    q = rng.normal(size=(4, 3, 6)) * np.array([1e-3, 1.0, 1e3, 1e6]).reshape(4, 1, 1)
    q_t = torch.from_numpy(q)  # float64: agreement to rounding
    np.testing.assert_allclose(soft_value_t(q_t, alpha).numpy(), soft_value(q, alpha), rtol=1e-12)
    np.testing.assert_allclose(boltzmann_t(q_t, alpha).numpy(), boltzmann(q, alpha), atol=1e-12)
    # float32, the trainer's dtype
    q32 = q_t.float()
    np.testing.assert_allclose(soft_value_t(q32, alpha).numpy(), soft_value(q, alpha), rtol=1e-5)
    np.testing.assert_allclose(boltzmann_t(q32, alpha).numpy(), boltzmann(q, alpha), atol=1e-4)


def test_tensor_alpha_per_row() -> None:
    q = torch.tensor([[0.0, math.log(3.0)], [0.0, math.log(3.0)]], dtype=torch.float64)
    alpha = torch.tensor([1.0, 0.5], dtype=torch.float64)
    np.testing.assert_allclose(boltzmann_t(q, alpha).numpy(), [[0.25, 0.75], [0.1, 0.9]])
    np.testing.assert_allclose(soft_value_t(q, alpha).numpy(), [math.log(4.0), 0.5 * math.log(10)])


def test_soft_value_gradient_is_the_boltzmann_policy() -> None:
    q = torch.tensor([[1.0, 2.0, 2.0, -1.0]], dtype=torch.float64, requires_grad=True)
    soft_value_t(q, 0.7).sum().backward()
    assert q.grad is not None
    np.testing.assert_allclose(q.grad.numpy(), boltzmann(q.detach().numpy(), 0.7), atol=1e-12)


def test_no_nan_for_extreme_inputs() -> None:
    q = torch.tensor([[3e38, -3e38, 0.0], [0.0, 0.0, 0.0]])
    for alpha in (1e-9, 1.0):
        assert torch.isfinite(boltzmann_t(q, alpha)).all()
        assert torch.isfinite(soft_value_t(q, alpha)).all()


def test_bad_alpha_and_shapes_are_rejected() -> None:
    q = torch.zeros(2, 3)
    for alpha in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="alpha"):
            boltzmann_t(q, alpha)
    with pytest.raises(ValueError, match="alpha"):
        soft_value_t(q, torch.tensor([1.0, 0.0]))
    with pytest.raises(ValueError, match=r"alpha: shape \(3,\)"):
        soft_value_t(q, torch.ones(3))
    with pytest.raises(ValueError, match="at least one action"):
        sample_boltzmann_t(torch.zeros(2, 0), 1.0)


def test_sampling_follows_the_policy_and_is_seeded() -> None:
    q = torch.tensor([[0.0, math.log(3.0), -50.0], [5.0, 5.0, 5.0]]).expand(20_000, 2, 3)
    actions = sample_boltzmann_t(q, 1.0, torch.Generator().manual_seed(3))
    assert actions.shape == (20_000, 2) and actions.dtype == torch.int64
    freq_row0 = torch.bincount(actions[:, 0], minlength=3).double() / 20_000
    freq_row1 = torch.bincount(actions[:, 1], minlength=3).double() / 20_000
    # standard error of a frequency near 1/2 with n = 20000 is ~0.0035; 0.02 is > 5 sigma
    np.testing.assert_allclose(freq_row0.numpy(), [0.25, 0.75, 0.0], atol=0.02)
    np.testing.assert_allclose(freq_row1.numpy(), [1 / 3] * 3, atol=0.02)
    again = sample_boltzmann_t(q, 1.0, torch.Generator().manual_seed(3))
    assert torch.equal(actions, again)
    greedy = sample_boltzmann_t(torch.tensor([[0.0, 1.0, 0.9]]), 1e-9)
    assert greedy.tolist() == [1]
