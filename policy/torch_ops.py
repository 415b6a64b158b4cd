"""The soft value and Boltzmann policy of `policy.maths`, in torch, for the trainer.

| function            | paper | input                 | output               |
|---------------------|-------|-----------------------|----------------------|
| `soft_value_t`      | eq. 3 | q (..., A), α         | (...), differentiable|
| `boltzmann_t`       | eq. 2 | q (..., A), α         | (..., A)             |
| `sample_boltzmann_t`| eq. 2 | q (..., A), α, gen    | int64 actions (...)  |

`alpha` is a positive float or a tensor broadcastable to the batch shape (...). Computation stays
in the dtype of `q` (the numpy versions use float64; the tests check agreement). As there,
exponents are taken of (q - max q) / α ≤ 0, so small α and large |Q| do not overflow.
"""

from __future__ import annotations

import math

import torch

__all__ = ["boltzmann_t", "sample_boltzmann_t", "soft_value_t"]


def _alpha_tensor(q: torch.Tensor, alpha: float | torch.Tensor) -> torch.Tensor:
    """α as a tensor of shape (..., 1) ready to divide `q`, or a ValueError."""
    if q.ndim < 1 or q.shape[-1] == 0:
        raise ValueError(f"q: expected shape (..., A) with at least one action, got {q.shape}")
    if isinstance(alpha, torch.Tensor):
        if not bool(torch.isfinite(alpha).all()) or bool((alpha <= 0).any()):
            raise ValueError(f"alpha: expected a positive finite temperature, got {alpha}")
        try:
            alpha_t = torch.broadcast_to(alpha.to(q.dtype), q.shape[:-1])
        except RuntimeError:
            raise ValueError(
                f"alpha: shape {tuple(alpha.shape)} does not broadcast to the batch shape "
                f"{tuple(q.shape[:-1])}"
            ) from None
        return alpha_t.unsqueeze(-1)
    if not math.isfinite(alpha) or alpha <= 0:
        raise ValueError(f"alpha: expected a positive finite temperature, got {alpha!r}")
    return torch.full((1,), float(alpha), dtype=q.dtype, device=q.device)


def soft_value_t(q: torch.Tensor, alpha: float | torch.Tensor) -> torch.Tensor:
    """V = α log Σ_a exp(Q(a) / α), shape (...); its gradient w.r.t. q is the Boltzmann policy."""
    a = _alpha_tensor(q, alpha)
    # the max is a constant shift (detached): the gradient still comes out as softmax(q / α)
    q_max = q.detach().amax(dim=-1, keepdim=True)
    v = q_max + a * torch.logsumexp((q - q_max) / a, dim=-1, keepdim=True)  # eq. 3
    return v.squeeze(-1)


def boltzmann_t(q: torch.Tensor, alpha: float | torch.Tensor) -> torch.Tensor:
    """π(a) ∝ exp(Q(a) / α), shape (..., A)."""
    a = _alpha_tensor(q, alpha)
    q_max = q.detach().amax(dim=-1, keepdim=True)
    return torch.softmax((q - q_max) / a, dim=-1)  # eq. 2


def sample_boltzmann_t(
    q: torch.Tensor, alpha: float | torch.Tensor, generator: torch.Generator | None = None
) -> torch.Tensor:
    """One action per row drawn from Boltzmann(q, α), int64 of shape (...)."""
    with torch.no_grad():
        probs = boltzmann_t(q, alpha)
        flat = probs.reshape(-1, probs.shape[-1]).float()
        if flat.shape[0] == 0:
            return torch.zeros(q.shape[:-1], dtype=torch.int64, device=q.device)
        actions = torch.multinomial(flat, 1, generator=generator)
    return actions.reshape(q.shape[:-1])
