"""`trainer.monitor`: goal monitors learn the domain's `goal_kept`, are gated on held-out states,
retried where the gate fails, and registered as `{env}/monitor/{goal}`; `coexist train monitor`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from cli.main import app
from envs.particle.domain import ParticleDomain
from model_store.sql import SqlModelStore
from policy.qnet import QNetSpec, qnet_from_safetensors
from trainer.monitor import (
    GATE_RETRIES,
    MonitorConfig,
    publish_monitors,
    train_gated,
    train_monitors,
)
from trainer.particle.monitor_states import LABEL_MARGIN, monitor_labels, monitor_states

DOMAIN = ParticleDomain()
SMALL = MonitorConfig(steps=800, states=128, hidden=(64, 64), holdout=1000)


def _accuracy(trained, goal_index: int, goal: str) -> tuple[float, float]:
    """(accuracy of the monitor's most likely label, the share of the majority label) on fresh
    states (a short training's probabilities are rarely as sure as the serving threshold)."""
    obs = monitor_states(np.random.default_rng(123), goal, 2000)
    truth = np.asarray(DOMAIN.goal_kept(obs, 2, goal), dtype=bool)
    views = torch.from_numpy(DOMAIN.task_views(obs, 2)[:, 0]).float()
    with torch.no_grad():
        logits = trained.nets(views[None].expand(trained.nets.n_members, -1, -1))[goal_index]
    called = logits.numpy() > 0.0
    return float((called == truth).mean()), float(max(truth.mean(), 1 - truth.mean()))


def test_a_monitor_learns_the_domain_s_goal_kept() -> None:
    trained = train_monitors(DOMAIN, monitor_states, ["a2", "c"], SMALL, seed=0)
    assert trained.goals == ("a2", "c")
    for g, goal in enumerate(trained.goals):
        accuracy, majority = _accuracy(trained, g, goal)
        assert accuracy > majority + 0.05  # better than always answering the common label
        gate = trained.gates[g]
        assert 0.0 <= gate.false_keeps <= 1.0 and 0.0 <= gate.misses <= 1.0
        assert gate.passed == (gate.false_keeps <= SMALL.max_false_keeps)


@pytest.mark.parametrize("goal", ["e0", "a2", "c", "3"])
def test_the_particle_labels_are_goal_kept_in_the_area_less_its_margin(goal: str) -> None:
    obs = monitor_states(np.random.default_rng(5), goal, 4000)
    truth = np.asarray(DOMAIN.goal_kept(obs, 2, goal), dtype=bool)
    labels = monitor_labels(obs, goal)
    assert labels.shape == truth.shape
    assert not (labels & ~truth).any()  # never keeping where the area itself is lost
    assert 0.5 * truth.sum() < labels.sum() < truth.sum()  # only the strip along the edge is lost


def test_resting_keeps_the_labels_area_only_inside_its_strip_but_up_to_a_wall() -> None:
    """Goal e0's target is x in [0.8, 1], y in [0, 0.2]: its left and top edges are inside the
    world, its right and bottom edges walls. Resting 0.003 left of it (the stranding state) and
    inside the strip is not kept; deeper inside, and in the corner on the two walls, it is."""
    rest = np.zeros((4, 8))
    rest[:, :2] = [[0.8 - 0.003, 0.1], [0.8 + LABEL_MARGIN / 2, 0.1], [0.9, 0.1], [1.0, 0.0]]
    assert monitor_labels(rest, "e0")[:, 0].tolist() == [False, False, True, True]
    assert DOMAIN.goal_kept(rest, 2, "e0")[:, 0].tolist() == [False, True, True, True]


def test_monitors_learn_the_labeller_s_answer_and_are_gated_on_goal_kept() -> None:
    """Trained on labels that never keep, a monitor calls nothing keeping: no false keeps (the
    gate passes) and every keeping action of `goal_kept` a miss."""
    never = np.zeros
    trained = train_monitors(
        DOMAIN,
        monitor_states,
        ["a2"],
        SMALL,
        seed=0,
        labels=lambda obs, goal: never((len(obs), DOMAIN.n_actions), dtype=bool),
    )
    gate = trained.gates[0]
    assert gate.false_keeps == 0.0 and gate.passed
    assert gate.misses == 1.0


def test_failed_gates_are_retrained_with_twice_the_steps() -> None:
    never = MonitorConfig(steps=5, states=16, hidden=(8,), holdout=50, max_false_keeps=-1.0)
    attempts = train_gated(DOMAIN, monitor_states, ["a2"], never, seed=3)
    assert [a.config.steps for a in attempts] == [5 * 2**k for k in range(GATE_RETRIES + 1)]
    assert len({a.seed for a in attempts}) == len(attempts)
    assert all(not a.gates[0].passed for a in attempts)


def test_published_monitors_load_and_only_passed_ones_get_the_alias(tmp_path: Path) -> None:
    config = MonitorConfig(steps=5, states=16, hidden=(8,), holdout=50, max_false_keeps=-1.0)
    trained = train_monitors(DOMAIN, monitor_states, ["a2"], config, seed=1)
    with SqlModelStore(f"sqlite:///{tmp_path}/models.db") as store:
        [version] = publish_monitors(store, trained, env="particle")
        assert version.name == "particle/monitor/a2"
        model = store.get_model(version.name)
        assert model.kind == "monitor" and model.aliases == {"latest": version.version}
        assert version.lineage.metrics["gate"]["passed"] is False
        net = qnet_from_safetensors(
            QNetSpec.from_json(version.spec), store.load_weights(version.name, version.version)
        )
        x = torch.rand(4, 8)
        torch.testing.assert_close(net(x), trained.nets(x[None])[0])


def test_the_command_trains_and_registers_and_refuses_an_env_without_states(
    tmp_path: Path,
) -> None:
    url = f"sqlite:///{tmp_path}/models.db"
    result = CliRunner().invoke(
        app, ["train", "monitor", "--goals", "a2", "--steps", "20", "--store-url", url]
    )
    assert result.exit_code in (0, 1), result.output  # 1: the short run failed its gate
    assert "monitors passed their gate" in result.output
    with SqlModelStore(url) as store:
        assert store.list_versions("particle/monitor/a2")
    refused = CliRunner().invoke(app, ["train", "monitor", "--env", "cooking", "--store-url", url])
    assert refused.exit_code == 2 and "--env" in refused.output


@pytest.mark.parametrize("goal", ["a2", "c", "3"])
def test_the_states_reach_the_target_s_edge(goal: str) -> None:
    """Where the answer changes: states on both sides of keeping, and boundary states."""
    obs = monitor_states(np.random.default_rng(0), goal, 4000)
    kept = np.asarray(DOMAIN.goal_kept(obs, 2, goal), dtype=bool)
    assert kept.all(axis=1).any() and (~kept).all(axis=1).any()
    assert (kept.any(axis=1) & ~kept.all(axis=1)).mean() > 0.05
