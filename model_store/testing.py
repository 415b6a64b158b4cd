"""Small artifacts for tests and examples: a Q-network spec and matching safetensors weights,
made with numpy (no torch, no training). Used by the store's, the REST API's and other parts'
tests; deterministic for a given seed."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np
import safetensors.numpy

from model_store.entities import Lineage

QNET_FORMAT = "coexist.qnet/v1"


def qnet_spec(
    obs_dim: int = 8,
    n_actions: int = 5,
    hidden: Sequence[int] = (16,),
    *,
    activation: str = "relu",
    dtype: str = "float32",
) -> dict[str, Any]:
    return {
        "format": QNET_FORMAT,
        "obs_dim": obs_dim,
        "n_actions": n_actions,
        "hidden": list(hidden),
        "activation": activation,
        "dtype": dtype,
    }


def qnet_tensors(spec: dict[str, Any], *, seed: int = 0, dtype: str = "float32") -> dict:
    """Random tensors named and shaped as the spec asks (`layers.k.weight` (out, in), ...)."""
    rng = np.random.default_rng(seed)
    widths = [spec["obs_dim"], *spec["hidden"], spec["n_actions"]]
    tensors: dict[str, np.ndarray] = {}
    for k, (n_in, n_out) in enumerate(itertools.pairwise(widths)):
        tensors[f"layers.{k}.weight"] = rng.normal(0, 0.1, (n_out, n_in)).astype(dtype)
        tensors[f"layers.{k}.bias"] = rng.normal(0, 0.1, (n_out,)).astype(dtype)
    return tensors


def qnet_weights(spec: dict[str, Any], *, seed: int = 0, dtype: str = "float32") -> bytes:
    """The bytes of a safetensors file matching `spec` (float32 or float16)."""
    return safetensors.numpy.save(qnet_tensors(spec, seed=seed, dtype=dtype))


def test_lineage(**overrides: Any) -> Lineage:
    """A plausible lineage for tests."""
    fields: dict[str, Any] = {
        "config": {"lr": 1e-3, "alpha": 0.1, "steps": 1000},
        "seed": 7,
        "code_version": "test",
        "metrics": {"final_return": 12.5},
        "parents": (),
        "registered_by": "pytest",
    }
    fields.update(overrides)
    return Lineage(**fields)


test_lineage.__test__ = False  # type: ignore[attr-defined]  # not a test for pytest
