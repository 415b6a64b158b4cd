"""The joint learner's gate (`trainer.particle.gates.joint_gates`) and `run_joint`'s retries of the
combinations that fail it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from envs.particle.goals import goal_index
from model_store.sql.sql_store import SqlModelStore
from policy.qnet import QNetSpec, StackedQNet
from tests.trainer.test_trainer_end_to_end import TINY
from trainer import zoo
from trainer.config import JointConfig, TaskConfig
from trainer.learners import TrainedBatch
from trainer.particle import learners as particle_learners
from trainer.particle.gates import JointGate, joint_gates
from trainer.particle.rollouts import ParticleJointRollout
from trainer.zoo import RunState, run_joint, run_tasks

SMALL: dict[str, Any] = dict(eval_episodes=16, eval_steps=40, alpha=0.02)
COMBOS: list[tuple[str, ...]] = [("a2", "b3"), ("c", "c4")]


def _nets(members: int, seed: int, *, resting: bool = False) -> StackedQNet:
    torch.manual_seed(seed)
    nets = StackedQNet(QNetSpec(obs_dim=8, n_actions=5, hidden=(16,)), members)
    if resting:  # prefers action 0 (no push) by far, wherever it is
        with torch.no_grad():
            for w in nets.weights:
                w.zero_()
            for b in nets.biases:
                b.zero_()
            nets.biases[-1][:, 0] = 10.0
    return nets


def _indices(combos: list[tuple[str, ...]]) -> list[list[int]]:
    return [[goal_index(g) for g in c] for c in combos]


def test_a_joint_network_that_acts_as_the_egos_task_network_passes_with_the_same_figures() -> None:
    """With two agents the JL's observation is the task network's view: the same network is SL
    itself, and on the same starts and random numbers earns exactly SL's figures."""
    ego = _nets(len(COMBOS), seed=0)
    partners = [_nets(len(COMBOS), seed=1)]
    config = replace(JointConfig(), **SMALL)
    gates = joint_gates(ego, _indices(COMBOS), ego, partners, config, seed=5)
    assert [g.goal for g in gates] == ["a2+b3", "c+c4"]
    for gate in gates:
        assert isinstance(gate, JointGate) and gate.passed, gate
        assert gate.success_rate == gate.sl_success_rate
        assert gate.team_return == gate.sl_team_return


def test_the_gate_compares_the_team_return_within_the_stated_margin() -> None:
    """A JL that only rests is judged by the same rule: passed exactly when its team return is
    within max(margin x |SL's|, slack) of SL's, however often its ego reaches its target."""
    ego, resting = _nets(len(COMBOS), seed=0), _nets(len(COMBOS), seed=0, resting=True)
    partners = [_nets(len(COMBOS), seed=1)]
    for slack in (0.0, 1e9):
        config = replace(JointConfig(), **SMALL, return_margin=0.0, return_slack=slack)
        for gate in joint_gates(resting, _indices(COMBOS), ego, partners, config, seed=5):
            assert gate.passed == (gate.team_return >= gate.sl_team_return - slack), gate


def _heads_for_the_centre_column() -> StackedQNet:
    """A task network for goal `c` (x in [0.4, 0.6], any y) by hand: push left right of x = 0.5,
    right left of it, never up or down; it reaches its target from any start."""
    nets = _nets(1, seed=0, resting=True)
    with torch.no_grad():
        nets.biases[-1][:, 0] = 0.0
        nets.weights[0][:, 0, 0], nets.biases[0][:, 0] = 1.0, -0.5  # relu(x - 0.5)
        nets.weights[0][:, 1, 0], nets.biases[0][:, 1] = -1.0, 0.5  # relu(0.5 - x)
        nets.weights[1][:, 3, 0], nets.weights[1][:, 3, 1] = 20.0, -20.0  # left
        nets.weights[1][:, 4, 0], nets.weights[1][:, 4, 1] = -20.0, 20.0  # right
        nets.biases[-1][:, 1:3] = -1.0  # up, down
    return nets


def test_a_joint_network_that_leaves_its_ego_outside_its_target_fails_at_the_defaults() -> None:
    """The gate a user would need: beside an SL that walks into its target, a JL that rests where
    it starts costs the team its distance every step, and fails at the default thresholds."""
    sl = _heads_for_the_centre_column()
    resting = _nets(1, seed=0, resting=True)
    partners = [_nets(1, seed=1)]
    config = replace(JointConfig(), **SMALL)
    (gate,) = joint_gates(resting, _indices([("c", "c4")]), sl, partners, config, seed=5)
    assert gate.sl_success_rate == 1.0 and gate.success_rate < 0.5, gate
    assert gate.team_return < gate.sl_team_return and not gate.passed, gate
    (same,) = joint_gates(sl, _indices([("c", "c4")]), sl, partners, config, seed=5)
    assert same.passed, same


def test_combinations_that_fail_train_again_with_twice_the_steps_and_a_fresh_seed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    store = SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}")
    run = RunState.open(tmp_path / "run", "fp", resume=False)
    common: dict[str, Any] = dict(seed=3, run=run, progress=lambda *_: lambda *__: None)
    tasks = replace(TaskConfig(), **TINY)
    run_tasks(store, ["a2", "b3", "c", "c4"], tasks, goals_per_batch=4, gate_retries=0, **common)

    def judged(nets: StackedQNet, combos: Any, ego: Any, partners: Any, config: Any, seed: int):
        # a2+b3 fails every time; c+c4 passes
        return [
            JointGate("+".join(map(str, c)), 1.0, 1.0, 0.0, 0.0, passed=c[0] != goal_index("a2"))
            for c in combos
        ]

    monkeypatch.setattr(particle_learners, "joint_gates", judged)
    batches: list[TrainedBatch] = run_joint(
        store, COMBOS, replace(JointConfig(), **TINY), gate_retries=2, **common
    )
    assert [b.goals for b in batches] == [COMBOS, [COMBOS[0]], [COMBOS[0]]]
    assert [b.config.total_steps for b in batches] == [60, 120, 240]
    assert [b.seed for b in batches] == [3 + 2000 + 2 + 7919 * a for a in range(3)]
    joint = "particle/joint/"
    assert store.resolve(f"{joint}a2+b3@latest").version == 3
    assert "production" not in store.get_model(f"{joint}a2+b3").aliases
    assert "production" in store.get_model(f"{joint}c+c4").aliases
    # resumed: nothing trains twice
    assert run_joint(store, COMBOS, replace(JointConfig(), **TINY), gate_retries=2, **common) == []
    assert zoo.joint_without(store, "particle", COMBOS, "production") == [COMBOS[0]]
    store.close()


def test_the_joint_rollout_ends_an_episode_when_every_agent_is_inside_its_target() -> None:
    """As the environment does: the transition is marked as an ending (no bootstrap) and the
    world restarts; a transition that does not end it is not marked."""
    config = replace(JointConfig(), **TINY)
    rollout = ParticleJointRollout(_indices([("c", "c4")]), [_nets(1, seed=1)], config, seed=0)
    inside = np.zeros((config.envs_per_net, 2, 4))
    inside[:, :, :2] = [0.5, 0.9]  # inside `c`'s target (x 0.4-0.6) and `c4`'s (also y 0.8-1)
    rollout.obs_BND = rollout.world.reset(inside)
    resting = np.zeros((1, config.envs_per_net), dtype=np.int64)
    rollout.step(resting)
    assert rollout.ended().shape == (1, config.envs_per_net) and rollout.ended().all()
    assert (rollout.world.steps == 0).all()  # restarted from random starts
    rollout.step(resting)
    assert not rollout.ended().any()
