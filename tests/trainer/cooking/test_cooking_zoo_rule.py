"""In the kitchen an impact network trains only against a `production` task network; the
training summary shows the kitchen's gate figures and says why an impact network is missing."""

from __future__ import annotations

import io
import logging
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

from model_store.entities import Lineage
from model_store.errors import NotFound
from model_store.naming import task_model_name
from model_store.sql.sql_store import SqlModelStore
from model_store.testing import qnet_spec, qnet_weights
from tests.trainer.cooking.tiny import TINY_COOKING_GATED
from trainer.backends.jobs import impact_jobs_with_parents, impact_stage
from trainer.config import ImpactConfig
from trainer.cooking.config import CookingImpactConfig, CookingTaskConfig
from trainer.cooking.gates import CookingTaskGate
from trainer.report import print_summary
from trainer.zoo import RunState, run_impacts, run_tasks

TINY = TINY_COOKING_GATED
GOAL = "CarrotBanana"


def _no_progress(description: str, total: int) -> Any:
    return lambda done, total_: None


def _summary(batches: list[Any]) -> str:
    console = Console(file=io.StringIO(), width=200)
    print_summary(batches, console)
    return console.file.getvalue()  # type: ignore[attr-defined]


def test_no_impact_network_beside_a_failed_task_network(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    store = SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}")
    common: dict[str, Any] = dict(progress=_no_progress, env="cooking", goals_per_batch=5)
    task_cfg = replace(CookingTaskConfig(), **TINY)
    impact_cfg = replace(CookingImpactConfig(), **TINY)
    run = RunState.open(tmp_path / "run", "fp", resume=False)
    tasks = run_tasks(store, [GOAL], task_cfg, seed=0, run=run, gate_retries=0, **common)
    assert tasks[0].gate_passed(0) is False  # 10-step gate episodes: no dish, no production
    text = _summary(tasks)
    assert "failed" in text and "0% in -" in text and "(scripted)" in text
    assert CookingTaskGate.FAILURE_NOTE.split(",")[0] in text.replace("\n", " ")

    with caplog.at_level(logging.WARNING, logger="trainer.zoo"):
        skipped = run_impacts(store, [GOAL], impact_cfg, seed=0, run=run, **common)
    assert skipped == []
    assert "impact CarrotBanana: skipped" in caplog.text and "'production'" in caplog.text
    with pytest.raises(NotFound):
        store.resolve(f"cooking/impact/{GOAL}@latest")

    # asked explicitly, the old fallback to `latest` still trains it (the particle default)
    loose = run_impacts(
        store,
        [GOAL],
        impact_cfg,
        seed=0,
        run=run,
        production_parents_only=False,
        gate_retries=0,
        **common,
    )
    assert store.resolve(f"cooking/impact/{GOAL}@latest").lineage.parents == (
        f"cooking/task/{GOAL}/1",
    )
    assert "partner" in _summary(loose) and "(resting ego)" in _summary(loose)

    # once a task network serves as `production`, the kitchen's zoo trains against it
    store.set_alias(f"cooking/task/{GOAL}", "production", 1)
    fresh = RunState.open(tmp_path / "run2", "fp2", resume=False)
    [batch] = run_impacts(store, [GOAL], impact_cfg, seed=0, run=fresh, gate_retries=0, **common)
    assert batch.goals == [(GOAL,)]
    store.close()


def test_the_ray_impact_stage_skips_the_goals_the_local_loop_skips(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """`impact_jobs_with_parents` (the Ray backend's impact stage) mirrors `run_impacts`: in the
    kitchen a goal whose task network has no `production` version leaves its job, the job
    keeps its seed and index and its key names the goals left; the particle world keeps all."""
    other = "OnionSoup"
    store = SqlModelStore(f"sqlite:///{tmp_path / 'models.db'}")
    spec = qnet_spec(obs_dim=8, n_actions=5, hidden=(4,))
    for goal, aliases in ((GOAL, ()), (other, ("production",))):
        name = task_model_name("cooking", goal)
        store.create_model(name, env="cooking", kind="task", goals=[goal], obs_dim=8, n_actions=5)
        store.register_version(
            name,
            spec=spec,
            weights=qnet_weights(spec, seed=1),
            lineage=Lineage(seed=1),
            aliases=aliases,
        )
    stage = impact_stage([GOAL, other, "BananaSmoothie"], ImpactConfig(), seed=3, per_batch=2)
    with caplog.at_level(logging.WARNING, logger="trainer.zoo"):
        jobs = impact_jobs_with_parents(store, "cooking", stage.jobs)
    assert "impact CarrotBanana,BananaSmoothie: skipped" in caplog.text
    [job] = jobs  # the second batch held only BananaSmoothie, which has no task network at all
    assert (job.members, job.key) == (((other,),), f"impact:{other}")
    assert (job.seed, job.index) == (stage.jobs[0].seed, 0)
    assert impact_jobs_with_parents(store, "particle", stage.jobs) == stage.jobs
    store.close()
