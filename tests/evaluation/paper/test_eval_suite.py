"""`coexist eval --suite paper --fast` end to end, and the server backend against the engine."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import uvicorn
from fastapi import FastAPI
from typer.testing import CliRunner

from cli.main import app
from evaluation.backend import EngineBackend, server_backend
from evaluation.config import Scenario
from evaluation.paper.report import SECTIONS
from evaluation.prepare import train_tiny_zoo
from evaluation.rollout import Cell, run_cells
from model_store.sql import SqlModelStore
from services.engine import ActRequest, InferenceEngine, PartnerSpec
from services.rest import install_error_handlers, router
from tests.evaluation.paper.test_eval_report import check_report_against_results


@pytest.mark.slow
def test_fast_suite_writes_every_section(tmp_path: Path) -> None:
    out = tmp_path / "report"
    (out).mkdir()
    (out / "discussion.md").write_text("Hand-written words.")
    run_dir = tmp_path / "zoo-run"
    run_dir.mkdir()
    (run_dir / "curves_task.png").write_bytes(b"png bytes")
    args = ["eval", "--suite", "paper", "--fast", "--out", str(out), "--run-dir", str(run_dir)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    report = (out / "REPORT.md").read_text()
    for section in SECTIONS:
        assert f"\n{section}" in report, section
    assert "coexist eval --suite paper --fast --episodes 6" in report
    assert "Hand-written words." in report
    assert "(fig4_zoo-run_task.png)" in report and (out / "fig4_zoo-run_task.png").exists()
    assert "| 1 | goal-aligned" in report and "| 4 | scaling" in report
    for png in (
        "fig5_two_agents",
        "fig7_five_agents",
        "fig6_directions",
        "episode_strip",
        "fig4_training",
        "fig_pairs",
    ):
        assert (out / f"{png}.png").stat().st_size > 1000, png
        assert f"({png}.png)" in report
    results = json.loads((out / "results.json").read_text())
    # every scenario table and every pair class's table of tests, against the episodes
    assert check_report_against_results(report, results) >= 6
    assert "p (Holm)" in report and "95 % CI (t)" in report and "TOST margin" in report
    cells = results["cells"]
    for scenario in ("aligned", "non_aligned", "five_agents"):
        for method in ("sl", "nail", "aail", "jl"):
            assert len(cells[f"{scenario}/{method}"]["returns"]) == (4 if "five" in scenario else 6)
    assert "particle/impact/b3" in report  # the models table names every network used


def test_unknown_suite_is_refused() -> None:
    result = CliRunner().invoke(app, ["eval", "--suite", "atari"])
    assert result.exit_code != 0
    assert "unknown suite" in result.output


def test_missing_networks_fail_before_any_episode(tmp_path: Path) -> None:
    store_url = f"sqlite:///{tmp_path}/empty.db"
    missing = CliRunner().invoke(app, ["eval", "--store-url", store_url, "--out", str(tmp_path)])
    assert missing.exit_code == 2 and "no SQLite database" in missing.output  # a mistyped path
    SqlModelStore(store_url).close()  # an empty store: it exists, it serves nothing
    result = CliRunner().invoke(app, ["eval", "--store-url", store_url, "--out", str(tmp_path)])
    assert result.exit_code == 2, result.output
    assert "not served" in result.output and "particle/task/b3@partners" in result.output
    assert not (tmp_path / "REPORT.md").exists()


@contextmanager
def live_http(engine: InferenceEngine) -> Iterator[str]:
    api = FastAPI()
    api.include_router(router)
    install_error_handlers(api)
    api.state.engine = engine
    server = uvicorn.Server(uvicorn.Config(api, host="127.0.0.1", port=0, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not server.started:
        assert time.monotonic() < deadline and thread.is_alive(), "uvicorn did not start"
        time.sleep(0.01)
    try:
        yield f"http://127.0.0.1:{server.servers[0].sockets[0].getsockname()[1]}"
    finally:
        server.should_exit = True
        thread.join(timeout=10)


@pytest.mark.slow
def test_server_backend_gives_the_engine_episodes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Through a real HTTP server the same episodes come out as in-process (common random
    numbers make the sampled actions a function of the probabilities alone)."""
    scenario = Scenario("non_aligned", "a2", ("b3",), 4, 2)
    with SqlModelStore(f"sqlite:///{tmp_path}/models.db") as store:
        train_tiny_zoo(store, ["a2"], ["b3"], [scenario.goals])
        engine = InferenceEngine(store)
        cells = [Cell(scenario, m) for m in ("sl", "nail", "aail", "aail_bounded", "jl")]
        local = run_cells(EngineBackend(engine), cells, max_steps=25, seed=1)
        with live_http(engine) as url:
            backend = server_backend(url)
            assert backend.has_models(ActRequest("particle", "a2", np.zeros((1, 8)), method="sl"))
            assert not backend.has_models(ActRequest("particle", "e4", np.zeros((1, 8))))
            remote = run_cells(backend, cells, max_steps=25, seed=1)
            # every field of the request reaches the server, the temperature and seed too
            obs = np.random.default_rng(0).uniform(-1, 1, (3, 8))
            for temperature in (None, 3.0):
                request = ActRequest(
                    "particle",
                    "a2",
                    obs,
                    (PartnerSpec(1, goal="b3"),),
                    temperature=temperature,
                    seed=7,
                )
                got, _ = backend.probs(request)
                want, _ = EngineBackend(engine).probs(request)
                np.testing.assert_allclose(got, want, rtol=1e-12)
            assert not np.allclose(got, backend.probs(replace(request, temperature=None))[0])
            bounded = replace(request, method="aail_bounded", regret_bound=0.0)
            np.testing.assert_allclose(
                backend.probs(bounded)[0], EngineBackend(engine).probs(bounded)[0], rtol=1e-12
            )
            # a request larger than one call may carry goes in slices, with the same answer
            monkeypatch.setattr("evaluation.backend.MAX_ROWS", 2)
            for sliced in (backend, EngineBackend(engine)):
                np.testing.assert_allclose(sliced.probs(request)[0], want, rtol=1e-12)
    for a, b in zip(local.results, remote.results, strict=True):
        np.testing.assert_allclose(a.returns_EN, b.returns_EN, rtol=1e-9)
        np.testing.assert_array_equal(a.length_E, b.length_E)
    assert local.models == remote.models
