"""Short training runs that register versions in a temporary store, and one network to its gate."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from model_store.sql.sql_store import SqlModelStore
from trainer.config import ImpactConfig, JointConfig, TaskConfig
from trainer.learners import train_tasks
from trainer.particle.gates import TaskGate
from trainer.zoo import (
    RunState,
    load_task_nets,
    retry_batches,
    run_impacts,
    run_joint,
    run_tasks,
)

TINY: dict[str, Any] = dict(
    total_steps=60,
    warmup_steps=10,
    envs_per_net=4,
    batch_size=16,
    hidden=(16,),
    eval_episodes=4,
    eval_steps=20,
)


def _no_progress(description: str, total: int):
    return lambda done, total_: None


def test_short_pipeline_registers_every_network_with_lineage(tmp_path: Path) -> None:
    store = SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}")
    run = RunState.open(tmp_path / "run", "fp", resume=False)
    task_cfg = replace(TaskConfig(), **TINY)
    common: dict[str, Any] = dict(seed=3, run=run, progress=_no_progress)
    tasks = run_tasks(
        store, ["a2", "b3", "c"], task_cfg, goals_per_batch=2, gate_retries=0, **common
    )
    assert [b.goals for b in tasks] == [[("a2",), ("b3",)], [("c",)]]
    impacts = run_impacts(
        store,
        ["b3", "c"],
        replace(ImpactConfig(), **TINY),
        goals_per_batch=5,
        gate_retries=0,
        **common,
    )
    run_joint(store, [["a2", "b3"]], replace(JointConfig(), **TINY), **common)

    task_v = store.resolve("particle/task/b3@latest")
    assert task_v.version == 1 and len(task_v.sha256) == 64
    assert task_v.lineage.seed == 3 and task_v.lineage.config["kind"] == "task"
    assert task_v.lineage.config["total_steps"] == 60
    assert "gate" in task_v.lineage.metrics and "curve" in task_v.lineage.metrics
    impact_v = store.resolve("particle/impact/b3@latest")
    assert impact_v.lineage.parents == ("particle/task/b3/1",)
    assert impact_v.spec["obs_dim"] == 8
    joint_v = store.resolve("particle/joint/a2+b3@latest")
    assert joint_v.spec["obs_dim"] == 8 and set(joint_v.lineage.parents) == {"particle/task/b3/1"}
    # production only where the gate passed (a 60-step network may or may not pass: it must agree)
    for batch in tasks + impacts:
        for g, goals in enumerate(batch.goals):
            model = store.get_model(f"particle/{batch.kind}/{goals[0]}")
            assert ("production" in model.aliases) == bool(batch.gate_passed(g))
            assert model.tags["gate"] == ("passed" if batch.gate_passed(g) else "failed")
    # the registered weights load back as the same networks
    nets, versions = load_task_nets(store, "particle", ["a2", "b3"], alias="latest")
    for k, v in nets.member_state(1).items():
        assert v.shape == tasks[0].nets.member_state(1)[k].shape
        assert (v == tasks[0].nets.member_state(1)[k]).all()
    assert [v.name for v in versions] == ["particle/task/a2", "particle/task/b3"]

    # resuming the same run does nothing twice
    again = run_tasks(
        store, ["a2", "b3", "c"], task_cfg, goals_per_batch=2, gate_retries=0, **common
    )
    assert again == [] and store.resolve("particle/task/a2@latest").version == 1
    reopened = RunState.open(tmp_path / "run", "fp", resume=True)
    assert set(reopened.done) == set(run.done)
    with pytest.raises(ValueError, match="other settings"):
        RunState.open(tmp_path / "run", "another-fingerprint", resume=True)
    store.close()


def test_training_is_deterministic_given_the_seed() -> None:
    cfg = replace(TaskConfig(), **TINY)
    first = train_tasks(["a0"], cfg, seed=5, evaluate=False)
    second = train_tasks(["a0"], cfg, seed=5, evaluate=False)
    for k, v in first.nets.member_state(0).items():
        assert (v == second.nets.member_state(0)[k]).all()


@pytest.mark.slow
def test_one_task_network_reaches_its_gate() -> None:
    cfg = TaskConfig()  # the default budget: the gate must pass with what `coexist train` uses
    batch = train_tasks(["b1"], cfg, seed=0)
    gate = batch.gates[0]
    assert isinstance(gate, TaskGate)
    assert gate.success_rate >= 0.95, gate
    assert gate.passed, gate


def test_goals_that_fail_their_gate_are_retrained_once_with_a_new_seed(tmp_path: Path) -> None:
    store = SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}")
    run = RunState.open(tmp_path / "run", "fp", resume=False)
    # 5 training steps cannot pass the gate: every goal fails, is retried once (two candidates
    # each, in two batches: trainer.zoo.retry_batches), and fails again
    cfg = replace(TaskConfig(), **{**TINY, "total_steps": 5, "warmup_steps": 1})
    batches = run_tasks(
        store,
        ["a2", "b3"],
        cfg,
        seed=1,
        goals_per_batch=2,
        run=run,
        progress=_no_progress,
        gate_retries=1,
    )
    assert [b.seed for b in batches] == [1, 1 + 7919, 1 + 7919 + 1]
    assert [b.goals for b in batches] == [
        [("a2",), ("b3",)],
        [("a2",), ("a2",)],
        [("b3",), ("b3",)],
    ]
    v3 = store.resolve("particle/task/b3@latest")
    assert v3.version == 3 and v3.lineage.seed == 1 + 7919 + 1
    assert "production" not in store.get_model("particle/task/b3").aliases
    assert set(run.done) == {"task:a2,b3", "task-retry-1:0", "task-retry-1:1", "task-retry-1"}
    again = run_tasks(
        store,
        ["a2", "b3"],
        cfg,
        seed=1,
        goals_per_batch=2,
        run=run,
        progress=_no_progress,
        gate_retries=1,
    )
    assert again == []  # resumed: neither the batch nor its retry runs twice
    store.close()


def test_a_retry_trains_two_candidates_of_every_failed_goal_in_one_batch_whatever_the_workers() -> (
    None
):
    assert retry_batches(["a2"]) == [["a2", "a2"]]
    assert retry_batches(["a2", "b3", "c"]) == [["a2", "b3", "a2", "b3"], ["c", "c"]]
    assert retry_batches([]) == []
