"""trainer.generic: an environment that brings only numbers trains with the generic machinery
(the corridor of tests/envs/tinyline), and a registration whose `training` is neither numbers
nor a trainer is refused with a message naming it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from envs.registry import EnvPlugin, env_plugin, register_env, unregister_env
from trainer.generic import GenericTaskConfig, GenericTrainer
from trainer.generic.gates import GenericImpactGate, GenericTaskGate, run_episodes
from trainer.generic.worlds import PairWorlds
from trainer.learners import train_impacts, train_tasks
from trainer.plugins import env_trainer


def test_the_corridor_trains_with_its_own_numbers(tinyline: str) -> None:
    trainer = env_trainer(tinyline)
    assert isinstance(trainer, GenericTrainer) and trainer.no_joint_reason
    task_cfg, impact_cfg = trainer.default_configs()
    assert task_cfg.env_name() == tinyline and task_cfg.hidden == (32, 32)
    task_cfg = replace(task_cfg, total_steps=300, eval_episodes=8)
    batch = train_tasks(["c1", "c3"], task_cfg, seed=0)
    assert batch.kind == "task" and batch.goals == [("c1",), ("c3",)]
    gates = [g for g in batch.gates if isinstance(g, GenericTaskGate)]
    assert [g.goal for g in gates] == ["c1", "c3"]
    assert all(np.isfinite(g.mean_return) and 0 <= g.success_rate <= 1 for g in gates)
    assert batch.curves.steps, "no training curve"
    impact_cfg = replace(impact_cfg, total_steps=200, eval_episodes=8)
    impacts = train_impacts(["c1", "c3"], batch.nets, impact_cfg, seed=1)
    assert impacts.kind == "impact" and len(impacts.gates) == 2
    assert isinstance(impacts.gates[0], GenericImpactGate)
    metrics = impacts.gates[0].metrics()
    assert {"partner_return", "partner_return_random_ego", "passed"} <= set(metrics)
    with pytest.raises(ValueError, match="joint-learner baseline"):
        trainer.train_joint([("c1", "c3")], [], task_cfg, seed=0, progress=None)


def test_pair_worlds_restart_ended_episodes(tinyline: str) -> None:
    worlds = PairWorlds(tinyline, ["c0"] * 4, ["c4"] * 4, episode_steps=3, seed=0)
    ends = 0
    for _ in range(6):
        _, next_B2D, done_B = worlds.step(np.zeros((4, 2), dtype=np.int64))
        assert next_B2D.shape == (4, 2, 2) and next_B2D.dtype == np.float32
        ends += int(done_B.sum())
    assert ends >= 8 and (worlds.t_B < 3).all()


def test_episodes_score_the_goal_the_domain_says_is_reached(tinyline: str) -> None:
    def walk_left(obs_B2D: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        # both walk left: the ego reaches c0 exactly when it starts left of its partner
        assert (obs_B2D[:, 0, 0] == obs_B2D[:, 1, 1]).all()  # each sees the other's cell
        return np.ones((len(obs_B2D), 2), dtype=np.int64)

    returns_B2, reached_B = run_episodes(
        tinyline, ["c0"] * 16, ["c4"] * 16, walk_left, steps=10, seed=3
    )
    assert set(reached_B.tolist()) == {0.0, 1.0}  # starts on both sides
    # an ego that arrived earned more than one stuck at c1 behind its partner for 10 steps
    assert returns_B2[reached_B == 1, 0].min() > returns_B2[reached_B == 0, 0].max()


def test_a_training_that_is_neither_numbers_nor_a_trainer_is_named(tinyline: str) -> None:
    plugin = env_plugin(tinyline)
    for training, words in (
        ("tinyline.nowhere:TRAINING", "does not resolve"),
        ("no-colon", "module:attribute"),
        ("tinyline.env:CELLS", "without default_configs"),
    ):
        register_env(replace(plugin, training=training), replace=True)
        env_trainer.cache_clear()
        try:
            with pytest.raises(ValueError, match=words):
                env_trainer(tinyline)
        finally:
            env_trainer.cache_clear()
    register_env(replace(plugin, training=None), replace=True)
    try:
        configs = env_trainer(tinyline).default_configs()
        assert configs[0] == GenericTaskConfig(env=tinyline)  # the default numbers
    finally:
        env_trainer.cache_clear()
        unregister_env(tinyline)


def test_coexists_own_worlds_keep_their_own_trainers() -> None:
    for env in ("particle", "cooking"):
        assert not isinstance(env_trainer(env), GenericTrainer)
        assert isinstance(env_plugin(env), EnvPlugin)
