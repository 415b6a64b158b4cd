"""`coexist eval --suite cooking` on a tiny store: the files of reports/cooking, the cooking
section of the paper report, the same episodes through a server, and refused options."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
from typer.testing import CliRunner

from cli.main import app
from evaluation.backend import EngineBackend, server_backend
from evaluation.cooking.report import (
    COOKING_HEADING,
    cooking_section,
    results_from_json,
    update_paper_report,
)
from evaluation.cooking.suite import evaluate_cooking
from model_store.sql.sql_store import SqlModelStore
from services.engine import InferenceEngine
from tests.evaluation.paper.test_eval_suite import (
    live_http,  # a uvicorn thread on 127.0.0.1 serving an engine
)
from tests.trainer.cooking.tiny import TINY_COOKING
from trainer.cooking.config import CookingImpactConfig, CookingTaskConfig
from trainer.learners import train_impacts, train_tasks
from trainer.publish import publish_batch

TINY = TINY_COOKING
FIG8 = ["TomatoLettuceSalad", "CarrotBanana"]


@pytest.fixture(scope="module")
def store_url(tmp_path_factory: pytest.TempPathFactory) -> str:
    """A tiny cooking zoo: the left cook's networks (`production`) and a right cook (`partners`)."""
    url = f"sqlite:///{tmp_path_factory.mktemp('cooking-cli') / 'models.db'}"
    with SqlModelStore(url) as store:
        task_cfg = replace(CookingTaskConfig(), **TINY)
        tasks = train_tasks(FIG8, task_cfg, seed=0, evaluate=False)
        publish_batch(store, tasks, env="cooking")
        impact_cfg = replace(CookingImpactConfig(), **TINY)
        partner_nets = train_tasks(["CarrotBanana"], task_cfg, seed=2, evaluate=False)
        impact = train_impacts(
            ["CarrotBanana"], partner_nets.nets, impact_cfg, seed=1, evaluate=False
        )
        publish_batch(store, impact, env="cooking")
        publish_batch(store, partner_nets, env="cooking", serve_alias="partners")
    return url


def test_cooking_suite_writes_results_and_the_paper_section(store_url: str, tmp_path: Path) -> None:
    out, paper = tmp_path / "cooking", tmp_path / "paper" / "REPORT.md"
    paper.parent.mkdir()
    paper.write_text("# Report\n\n## Verdicts\n\nyes\n\n## Discussion\n\nwords\n")
    args = [
        "eval",
        "--suite",
        "cooking",
        "--store-url",
        store_url,
        "--episodes",
        "3",
        "--max-steps",
        "12",
        "--seed",
        "5",
        "--out",
        str(out),
    ]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    data = json.loads((out / "results.json").read_text())
    assert data["episodes"] == 3 and data["max_steps"] == 12 and data["seed"] == 5
    assert data["command"].startswith("coexist eval --suite cooking --store-url")
    assert "--episodes 3 --max-steps 12 --seed 5" in data["command"]
    assert data["right_cook"].startswith("learned") and set(data["summary"]) == {
        "aail_bounded/left",
        "aail_bounded/right",
        "aail_budget/left",
        "aail_budget/right",
        "aail/left",
        "aail/right",
        "sl/left",
        "sl/right",
    }
    again = results_from_json(data)
    assert again.served_MEN.shape == (4, 3, 2) and again.completion("sl", 0).mean == 0.0
    for name in ("results.md", "fig9_cooking.png", "aail_episode.gif"):
        assert (out / name).stat().st_size > 100, name
    report = paper.read_text()
    assert report.count(COOKING_HEADING) == 1 and "words" in report
    assert "](../cooking/fig9_cooking.png)" in report and "| AAIL |" in report
    # a second run replaces the section instead of adding one
    assert CliRunner().invoke(app, args).exit_code == 0
    assert paper.read_text().count(COOKING_HEADING) == 1


def test_the_same_episodes_through_a_server(store_url: str) -> None:
    with SqlModelStore(store_url) as store:
        engine = InferenceEngine(store)
        local = evaluate_cooking(EngineBackend(engine), episodes=2, max_steps=8, seed=3)
        with live_http(engine) as url:
            remote = evaluate_cooking(server_backend(url), episodes=2, max_steps=8, seed=3)
            # the temperature reaches the server (it was dropped once)
            warm = evaluate_cooking(
                server_backend(url), episodes=2, max_steps=8, seed=3, temperature=5.0
            )
        warm_local = evaluate_cooking(
            EngineBackend(engine), episodes=2, max_steps=8, seed=3, temperature=5.0
        )
    assert (local.returns_MEN == remote.returns_MEN).all()
    assert (warm.served_MEN == warm_local.served_MEN).all()
    assert (warm.returns_MEN == warm_local.returns_MEN).all()
    assert local.models == remote.models and remote.right_cook.startswith("learned")


def test_missing_networks_and_paper_options_are_refused(tmp_path: Path) -> None:
    empty = f"sqlite:///{tmp_path / 'empty.db'}"
    SqlModelStore(empty).close()  # an empty store: it exists, it serves nothing
    args = ["eval", "--suite", "cooking", "--store-url", empty, "--out", str(tmp_path / "c")]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2 and "not served" in result.output
    assert not (tmp_path / "c" / "results.json").exists()
    refused = CliRunner().invoke(app, [*args, "--pairs", "3"])
    assert refused.exit_code != 0 and "not used by the cooking suite" in refused.output


def test_the_section_before_any_cooking_run(tmp_path: Path) -> None:
    section = cooking_section(tmp_path / "cooking", tmp_path / "paper")
    assert section.startswith(COOKING_HEADING) and "Not run yet" in section
    assert not update_paper_report(tmp_path / "paper" / "REPORT.md", section)  # no report
