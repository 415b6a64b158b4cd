"""A short cooking pipeline into a temporary store, served by the inference engine; the CLI."""

from __future__ import annotations

import functools
import io
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from rich.console import Console
from typer.testing import CliRunner

from cli.main import app
from envs.cooking import BatchedCookingWorld
from model_store.errors import NotFound
from model_store.sql.sql_store import SqlModelStore
from policy.qnet import QNetSpec, StackedQNet
from services.engine import ActRequest, InferenceEngine, PartnerSpec
from tests.trainer.cooking.tiny import TINY_COOKING_GATED
from trainer.config import GATE_RETRIES, TaskConfig
from trainer.cooking import config as cooking_config
from trainer.cooking.config import CookingImpactConfig, CookingTaskConfig
from trainer.cooking.gates import (
    CookingImpactGate,
    CookingTaskGate,
    cooking_impact_gates,
    print_cooking_gates,
)
from trainer.cooking.learners import train_cooking_tasks
from trainer.jobs.spec import GATE_FAILED_EXIT_CODE
from trainer.zoo import RunState, run_impacts, run_tasks

TINY = {**TINY_COOKING_GATED, "total_steps": 30}
FIG8 = ["TomatoLettuceSalad", "CarrotBanana"]


def _no_progress(description: str, total: int) -> Any:
    return lambda done, total_: None


def test_cooking_pipeline_registers_networks_the_engine_serves(tmp_path: Path) -> None:
    store = SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}")
    task_cfg = replace(CookingTaskConfig(), **TINY)
    impact_cfg = replace(CookingImpactConfig(), **TINY)
    common: dict[str, Any] = dict(progress=_no_progress, env="cooking", goals_per_batch=5)
    run = RunState.open(tmp_path / "run", "fp", resume=False)
    tasks = run_tasks(store, FIG8, task_cfg, seed=0, run=run, gate_retries=0, **common)
    # tiny task networks fail their gates: train the impact network against `latest` anyway
    impacts = run_impacts(
        store,
        ["CarrotBanana"],
        impact_cfg,
        seed=0,
        run=run,
        production_parents_only=False,
        **common,
    )
    partners = RunState.open(tmp_path / "partners", "fp2", resume=False)
    run_tasks(
        store,
        ["CarrotBanana"],
        task_cfg,
        seed=1,
        run=partners,
        serve_alias="partners",
        gate_retries=0,
        **common,
    )

    task_v = store.resolve("cooking/task/TomatoLettuceSalad@latest")
    assert task_v.spec["obs_dim"] == 188 and task_v.spec["n_actions"] == 5
    assert task_v.lineage.config["gamma"] == 0.98 and task_v.lineage.config["kind"] == "task"
    gate = task_v.lineage.metrics["gate"]
    assert {"completion_rate", "scripted_completion_rate", "passed"} <= set(gate)
    impact_v = store.resolve("cooking/impact/CarrotBanana@latest")
    assert impact_v.lineage.parents == ("cooking/task/CarrotBanana/1",)
    assert store.resolve("cooking/task/CarrotBanana@latest").version == 2  # the partner one
    assert isinstance(tasks[0].gates[0], CookingTaskGate)
    assert isinstance(impacts[0].gates[0], CookingImpactGate)
    for batch in tasks + impacts:  # production exactly where the gate passed
        for g, goals in enumerate(batch.goals):
            model = store.get_model(f"cooking/{batch.kind}/{goals[0]}")
            assert ("production" in model.aliases) == bool(batch.gate_passed(g))

    # served by the domain-generic engine: AAIL for the left cook, SL for the right
    obs_BND = BatchedCookingWorld("coexistence", np.array([FIG8] * 3)).observe()
    engine = InferenceEngine(store)
    results = engine.act(
        ActRequest(
            env="cooking",
            ego_goal="TomatoLettuceSalad",
            observations=obs_BND[:, 0],
            partners=(PartnerSpec(index=1, goal="CarrotBanana"),),
            alias="latest",
            seed=0,
        )
    )
    assert len(results) == 3
    for r in results:
        assert len(r.probs) == 5 and abs(sum(r.probs) - 1) < 1e-9 and 0 <= r.action < 5
        assert [m.name for m in r.models] == [
            "cooking/task/TomatoLettuceSalad",
            "cooking/impact/CarrotBanana",
        ]
    [right] = engine.act(
        ActRequest(
            env="cooking",
            ego_goal="CarrotBanana",
            observations=obs_BND[:1, 1],
            method="sl",
            alias="latest",
        )
    )
    assert right.models[0].version == 2  # `latest` moved to the partner population's network
    store.close()


def test_a_config_for_another_world_is_refused(tmp_path: Path) -> None:
    store = SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}")
    run = RunState.open(tmp_path / "run", "fp", resume=False)
    with pytest.raises(ValueError, match="does not train env 'cooking'"):
        run_tasks(
            store,
            FIG8,
            TaskConfig(),
            seed=0,
            goals_per_batch=5,
            run=run,
            progress=_no_progress,
            env="cooking",
        )
    with pytest.raises(ValueError, match="does not train env 'particle'"):
        run_tasks(
            store,
            ["a2"],
            CookingTaskConfig(),
            seed=0,
            goals_per_batch=5,
            run=run,
            progress=_no_progress,
        )
    store.close()


def test_task_gate_compares_with_the_scripted_cook() -> None:
    cfg = replace(CookingTaskConfig(), **{**TINY, "eval_episodes": 3, "eval_steps": 60})
    batch = train_cooking_tasks(["ChoppedTomato"], cfg, seed=4)
    [gate] = batch.gates
    assert isinstance(gate, CookingTaskGate)
    assert gate.scripted_completion_rate == 1.0  # the planner chops a tomato in < 60 steps
    assert gate.scripted_mean_steps_to_dish is not None
    assert 8 <= gate.scripted_mean_steps_to_dish <= 40
    assert gate.passed == (gate.completion_rate > 0 and gate.completion_rate >= 0.8)
    console = Console(file=io.StringIO(), width=160)
    print_cooking_gates([batch], console)
    table = console.file.getvalue()  # type: ignore[attr-defined]
    assert "task ChoppedTomato" in table and "100% (scripted cook)" in table


def _always(action: int) -> StackedQNet:
    """A one-member network that prefers `action` by 9 in every state."""
    net = StackedQNet(QNetSpec(obs_dim=188, n_actions=5, hidden=(4,)), 1)
    with torch.no_grad():
        for w, b in zip(net.weights, net.biases, strict=True):
            w.zero_()
            b.zero_()
        net.biases[-1][0, action] = 9.0
    return net


def test_impact_gate_sees_no_difference_when_the_ego_rests_anyway() -> None:
    cfg = replace(CookingImpactConfig(), **{**TINY, "eval_episodes": 3, "eval_steps": 40})
    partner = train_cooking_tasks(
        ["CarrotBanana"], replace(CookingTaskConfig(), **TINY), seed=5, evaluate=False
    ).nets
    [gate] = cooking_impact_gates(_always(0), partner, ["CarrotBanana"], cfg, seed=6)
    # the partner draws the same random numbers beside either ego: identical episodes
    assert gate.partner_completion_rate == gate.partner_completion_rate_resting_ego
    assert gate.partner_return == gate.partner_return_resting_ego
    assert not gate.helps
    # no harm, but the partner (an untrained cook: no dish) needed help and got none
    assert gate.partner_completion_rate_resting_ego < cfg.min_help_rate and not gate.passed
    [lenient] = cooking_impact_gates(
        _always(0), partner, ["CarrotBanana"], replace(cfg, min_help_rate=0.0), seed=6
    )
    assert lenient.passed


def test_train_zoo_cli_for_the_kitchen(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("CookingTaskConfig", "CookingImpactConfig"):
        tiny = functools.partial(getattr(cooking_config, name), **TINY)
        monkeypatch.setattr(cooking_config, name, tiny)
    url = f"sqlite:///{tmp_path / 'models.db'}"
    args = [
        "train",
        "zoo",
        "--env",
        "cooking",
        "--goals",
        ",".join(FIG8),
        "--steps",
        "12",
        "--store-url",
        url,
        "--run-dir",
        str(tmp_path / "run"),
    ]
    result = CliRunner().invoke(app, args)
    # the tiny networks fail their gates: trained and registered, and the exit status says so
    assert result.exit_code == GATE_FAILED_EXIT_CODE, result.output
    assert "gate failed: task CarrotBanana:" in result.output
    store = SqlModelStore(url)
    for name in ("task/TomatoLettuceSalad", "task/CarrotBanana"):
        v = store.resolve(f"cooking/{name}@latest")
        assert v.lineage.config["total_steps"] == 12
    # the tiny task networks failed their gates: no impact network against them (trainer.zoo)
    # the first attempt and GATE_RETRIES retries of two candidates each (trainer.zoo.retry_batches)
    assert (
        max(v.version for v in store.list_versions("cooking/task/CarrotBanana"))
        == 1 + 2 * GATE_RETRIES
    )
    with pytest.raises(NotFound):
        store.resolve("cooking/impact/CarrotBanana@latest")
    assert "impact networks train only against `production`" in " ".join(result.output.split())
    store.close()
    refused = CliRunner().invoke(
        app, ["train", "joint", "--env", "cooking", "--combos", "TomatoLettuceSalad+CarrotBanana"]
    )
    assert refused.exit_code != 0 and "particle world only" in refused.output
