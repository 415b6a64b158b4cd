"""`coexist eval --suite pairs`: every method on goal pairs of a plugin environment (the corridor
of tests/envs/tinyline, registered from code), through the in-process engine over a tiny zoo."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from evaluation.backend import EngineBackend
from evaluation.base import Bars, EvalOptions, OptionError
from evaluation.pairs.command import METHODS, PAIRS_SUITE
from evaluation.pairs.rollout import goal_pairs, run_method
from evaluation.suites import get_suite
from model_store.sql.sql_store import SqlModelStore
from services.engine import InferenceEngine
from trainer.learners import train_impacts, train_tasks
from trainer.plugins import env_trainer
from trainer.publish import publish_batch

GOALS = ["c0", "c1", "c2", "c3", "c4"]


class _QuietUi:
    def __init__(self) -> None:
        self.printed: list[str] = []

    def print(self, text: str) -> None:
        self.printed.append(text)

    @contextmanager
    def progress(self, unit: str) -> Iterator[Bars]:
        def bar(label: str, total: int) -> Callable[[int, int], None]:
            return lambda step, count: None

        yield bar


@pytest.fixture
def zoo(tinyline: str, tmp_path: Path) -> str:
    """The corridor's task and impact networks for every goal, briefly trained (the alias
    `latest`: a gate need not pass); the store's URL."""
    url = f"sqlite:///{tmp_path / 'zoo' / 'models.db'}"
    (tmp_path / "zoo").mkdir()
    store = SqlModelStore(url)
    task_cfg, impact_cfg = env_trainer(tinyline).default_configs()
    tasks = train_tasks(GOALS, replace(task_cfg, total_steps=300), seed=0, evaluate=False)
    publish_batch(store, tasks, env=tinyline)
    impacts = train_impacts(
        GOALS, tasks.nets, replace(impact_cfg, total_steps=200), seed=1, evaluate=False
    )
    publish_batch(store, impacts, env=tinyline)
    store.close()
    return url


def test_every_method_on_goal_pairs_with_paired_statistics(
    tinyline: str, zoo: str, tmp_path: Path
) -> None:
    out = tmp_path / "report"
    options = EvalOptions(
        env=tinyline, store_url=zoo, alias="latest", pairs=3, pair_episodes=4, max_steps=12,
        seed=5, out=out,
    )  # fmt: skip
    ui = _QuietUi()
    run = PAIRS_SUITE.run(options, ui)
    PAIRS_SUITE.write_report(run, options, ui)
    results = json.loads((out / "results.json").read_text())
    assert list(results["methods"]) == list(METHODS)
    assert len(results["pairs"]) == 3 and all(a != b for a, b in results["pairs"])
    assert results["default"] == "aail_bounded"
    for row in results["methods"].values():
        assert row["episodes"] == 12
        assert 0 <= row["ego_success"]["mean"] <= 1
        low, high = row["team_return"]["ci95"]
        assert low <= row["team_return"]["mean"] <= high
    assert results["methods"]["sl"]["stranded"] == results["methods"]["sl"]["rescued"] == 0
    assert set(results["versus_sl"]["team_return"]) == set(METHODS) - {"sl"}
    assert results["command"].startswith("coexist eval --suite pairs --env tinyline --seed 5")
    assert '"sqlite:///$ZOO/models.db"' in results["command"]
    assert str(tmp_path) not in (out / "REPORT.md").read_text()
    assert "$ZOO" in (out / "REPORT.md").read_text()

    # common random numbers: the same seed gives SL the same episodes; aail_budget carries its
    # episode budget from step to step through the engine's answers
    store = SqlModelStore(zoo)
    backend = EngineBackend(InferenceEngine(store))
    pairs = goal_pairs(GOALS, 2, seed=1)
    kwargs: dict[str, Any] = {"episodes": 3, "seed": 2, "max_steps": 10, "alias": "latest"}
    once = run_method(backend, tinyline, pairs, "sl", **kwargs)
    again = run_method(backend, tinyline, pairs, "sl", **kwargs)
    np.testing.assert_array_equal(once.ego_return, again.ego_return)
    np.testing.assert_array_equal(once.team_return, again.team_return)
    budget = run_method(backend, tinyline, pairs, "aail_budget", **kwargs)
    assert budget.ego_return.shape == (2, 3) and (budget.length <= 10).all()
    store.close()


def test_goal_pairs_are_every_ordered_pair_or_a_seeded_draw() -> None:
    every = goal_pairs(["a", "b", "c"], None, seed=0)
    assert every == [("a", "b"), ("a", "c"), ("b", "a"), ("b", "c"), ("c", "a"), ("c", "b")]
    assert goal_pairs(["a", "b", "c"], 4, seed=3) == goal_pairs(["a", "b", "c"], 4, seed=3)
    assert set(goal_pairs(["a", "b", "c"], 4, seed=3)) < set(every)


@pytest.mark.parametrize(
    ("options", "flag"),
    [
        (EvalOptions(), "--env"),
        (EvalOptions(env="nowhere"), "--env"),
        (EvalOptions(env="particle", episodes=3), "--episodes"),
        (EvalOptions(env="particle", pairs=0), "--pairs"),
    ],
)
def test_refused_options_are_named(options: EvalOptions, flag: str) -> None:
    with pytest.raises(OptionError) as refused:
        PAIRS_SUITE.run(options, _QuietUi())
    assert refused.value.option == flag


@pytest.mark.parametrize("name", ["paper", "inference", "cooking", "partners"])
def test_the_other_suites_refuse_env(name: str) -> None:
    """`--env` chooses the pairs suite's world only: a suite of one world names it, not ignores it."""
    with pytest.raises(OptionError) as refused:
        get_suite(name).run(EvalOptions(env="mpe2_landmarks"), _QuietUi())
    assert refused.value.option == "--env"
