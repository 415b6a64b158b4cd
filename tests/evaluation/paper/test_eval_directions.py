"""Fig. 6 maths: grid observations, expected directions, and the impact policy alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from evaluation.backend import EngineBackend
from evaluation.paper.directions import (
    box_centre,
    direction_fields,
    expected_direction,
    grid_observations,
    impact_probs,
)
from evaluation.prepare import train_tiny_zoo
from model_store.sql import SqlModelStore
from services.engine import ActRequest, InferenceEngine, PartnerSpec


def test_expected_direction_by_hand() -> None:
    probs = np.array([[0, 1, 0, 0, 0], [0.2] * 5, [0.5, 0, 0, 0, 0.5], [0, 0.25, 0.75, 0, 0]])
    expected = np.array([[0, 1], [0, 0], [0.5, 0], [0, -0.5]], dtype=float)
    np.testing.assert_allclose(expected_direction(probs), expected, atol=1e-12)


def test_grid_observations_put_the_partner_at_rest_in_its_target() -> None:
    assert box_centre("b3") == pytest.approx((0.3, 0.7))
    positions, obs = grid_observations("b3", 2)
    np.testing.assert_allclose(positions, [[0.25, 0.25], [0.75, 0.25], [0.25, 0.75], [0.75, 0.75]])
    np.testing.assert_allclose(obs[:, :2], positions)
    np.testing.assert_allclose(obs[:, 4:6], [[0.3, 0.7]] * 4, rtol=1e-6)
    assert not obs[:, [2, 3, 6, 7]].any()
    with pytest.raises(ValueError, match="grid"):
        grid_observations("b3", 1)


def test_impact_policy_is_what_nail_averages(tmp_path: Path) -> None:
    """NAIL = Boltzmann((Q_t + Q_i) / 2) at one α, so π_i ∝ π_NAIL² / π_SL: the impact panel
    computed from the store agrees with the engine's NAIL and SL answers."""
    with SqlModelStore(f"sqlite:///{tmp_path}/models.db") as store:
        train_tiny_zoo(store, ["a2"], ["b3"], [])
        backend = EngineBackend(InferenceEngine(store))
        fields = {f.label: f for f in direction_fields(backend, store, "a2", "b3", grid=4)}
        assert list(fields) == ["task (SL)", "impact", "NAIL", "AAIL"]
        _, obs = grid_observations("b3", 4)
        impact = impact_probs(store, "particle", "b3", "production", obs)

        def probs(method: str) -> np.ndarray:
            request = ActRequest("particle", "a2", obs, (PartnerSpec(1, goal="b3"),), method)  # type: ignore[arg-type]
            return backend.probs(request)[0]

        logits = 2 * np.log(probs("nail")) - np.log(probs("sl"))
        derived = np.exp(logits - logits.max(axis=1, keepdims=True))
        derived /= derived.sum(axis=1, keepdims=True)
        np.testing.assert_allclose(impact, derived, atol=1e-5)
        np.testing.assert_allclose(fields["impact"].accel_B2, expected_direction(impact))
        assert len(direction_fields(backend, None, "a2", "b3", grid=3)) == 3  # no store: no impact
