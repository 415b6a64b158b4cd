"""`publish_batch`: each member's lineage holds its own training curve, point for point."""

from __future__ import annotations

from pathlib import Path

from model_store.sql import SqlModelStore
from policy.qnet import QNetSpec, StackedQNet
from trainer.config import TaskConfig
from trainer.learners import TrainedBatch
from trainer.loop import TrainingCurves
from trainer.publish import publish_batch

SPEC = QNetSpec(obs_dim=8, n_actions=5, hidden=(8,))


def _batch(curves: TrainingCurves) -> TrainedBatch:
    goals: list[tuple[str, ...]] = [("a2",), ("b3",)]
    return TrainedBatch("task", goals, StackedQNet(SPEC, 2), SPEC, TaskConfig(), 3, curves)


def test_each_version_stores_its_members_column_of_the_curve(tmp_path: Path) -> None:
    curves = TrainingCurves(
        steps=[100, 200, 300],
        returns_G=[[-9.0, -7.5], [-4.0, -8.0], [-2.5, -6.0]],
        losses_G=[[1.0, 2.0], [0.5, 1.5], [0.25, 1.25]],
    )
    with SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}") as store:
        a2, b3 = publish_batch(store, _batch(curves))
        stored_a2 = store.get_version(a2.name, a2.version).lineage.metrics
        stored_b3 = store.get_version(b3.name, b3.version).lineage.metrics
    assert stored_a2["training_curve"] == {
        "steps": [100, 200, 300],
        "mean_return": [-9.0, -4.0, -2.5],
        "loss": [1.0, 0.5, 0.25],
    }
    assert stored_b3["training_curve"] == {
        "steps": [100, 200, 300],
        "mean_return": [-7.5, -8.0, -6.0],
        "loss": [2.0, 1.5, 1.25],
    }
    # the summary agrees with the curve it summarises
    assert stored_b3["curve"] == {
        "first": -7.5,
        "best": -6.0,
        "final": -6.0,
        "points": 3,
        "steps": 300,
    }


def test_a_run_too_short_for_a_curve_point_stores_no_curve(tmp_path: Path) -> None:
    with SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}") as store:
        a2, _ = publish_batch(store, _batch(TrainingCurves()))
        metrics = store.get_version(a2.name, a2.version).lineage.metrics
    assert "training_curve" not in metrics and metrics["curve"] == {}
