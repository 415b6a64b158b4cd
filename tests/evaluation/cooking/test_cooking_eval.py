"""The cooking evaluation (paper Fig. 9), fast: a tiny zoo, a few short paired episodes."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from evaluation.cooking.suite import (
    CookingResults,
    evaluate_cooking,
    plot_cooking,
    save_cooking_gif,
)
from model_store.sql.sql_store import SqlModelStore
from services.engine import InferenceEngine
from tests.trainer.cooking.tiny import TINY_COOKING
from trainer.cooking.config import CookingImpactConfig, CookingTaskConfig
from trainer.learners import train_impacts, train_tasks
from trainer.publish import publish_batch
from trainer.zoo import load_task_nets

TINY = TINY_COOKING
FIG8 = ["TomatoLettuceSalad", "CarrotBanana"]


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> SqlModelStore:
    """Task and impact networks (`production`) and a partner population (`partners`)."""
    path = tmp_path_factory.mktemp("cooking") / "models.db"
    store = SqlModelStore(f"sqlite:///{path}")
    task_cfg = replace(CookingTaskConfig(), **TINY)
    tasks = train_tasks(FIG8, task_cfg, seed=0, evaluate=False)
    publish_batch(store, tasks, env="cooking")
    impact_cfg = replace(CookingImpactConfig(), **TINY)
    partner_nets, _ = load_task_nets(store, "cooking", ["CarrotBanana"])
    impact = train_impacts(["CarrotBanana"], partner_nets, impact_cfg, seed=1, evaluate=False)
    publish_batch(store, impact, env="cooking")
    partners = train_tasks(["CarrotBanana"], task_cfg, seed=2, evaluate=False)
    publish_batch(store, partners, env="cooking", serve_alias="partners")
    return store


def test_paired_episodes_through_the_engine(store: SqlModelStore, tmp_path: Path) -> None:
    engine = InferenceEngine(store)
    results = evaluate_cooking(engine, store, episodes=3, seed=4, max_steps=15)
    assert results.methods == ("aail_bounded", "aail_budget", "aail", "sl")
    assert results.episodes == 3
    assert results.served_MEN.shape == results.returns_MEN.shape == (4, 3, 2)
    assert results.right_cook.startswith("learned")
    # no dish fits in 15 steps (the salad alone takes >= 20): every step costs 0.01
    assert not results.served_MEN.any()
    np.testing.assert_allclose(results.returns_MEN, -0.15)
    assert results.completion("aail", 1).mean == 0.0
    assert results.models["aail"] == [
        "cooking/task/TomatoLettuceSalad/1",
        "cooking/impact/CarrotBanana/1",
    ]
    assert results.models["partner"] == ["cooking/task/CarrotBanana/2"]
    assert len(results.trajectory) == 16  # the start and 15 steps of the first AAIL episode

    # common random numbers: SL's episodes do not depend on what else is evaluated beside them
    alone = evaluate_cooking(engine, store, episodes=3, seed=4, max_steps=15, methods=("sl",))
    np.testing.assert_array_equal(alone.returns_MEN[0], results.returns_MEN[3])
    first = [
        s.agent_rc
        for s in evaluate_cooking(
            engine, store, episodes=3, seed=4, max_steps=15, methods=("sl",), record="sl"
        ).trajectory
    ]
    again = [
        s.agent_rc
        for s in evaluate_cooking(
            engine, store, episodes=3, seed=4, max_steps=15, methods=("aail", "sl"), record="sl"
        ).trajectory
    ]
    assert all((a == b).all() for a, b in zip(first, again, strict=True))

    text = results.to_markdown()
    assert (
        "| AAIL |" in text
        and "| SL |" in text
        and "McNemar" in text
        and "Paper (AAIL - SL):" in text
    )
    png = plot_cooking(results, tmp_path / "fig9.png")
    assert png.stat().st_size > 1000
    gif = save_cooking_gif(results, tmp_path / "episode.gif")
    with Image.open(gif) as image:
        assert 1 < getattr(image, "n_frames", 1) <= 16  # (a GIF merges repeated frames)


def test_right_cook_falls_back_to_the_scripted_cook(store: SqlModelStore) -> None:
    results = evaluate_cooking(
        InferenceEngine(store), episodes=2, seed=0, max_steps=5, partner_alias="nobody", record=None
    )
    assert results.right_cook.startswith("scripted") and "partner" not in results.models
    assert results.trajectory == []


def test_bad_arguments_are_refused(store: SqlModelStore) -> None:
    with pytest.raises(ValueError, match="episodes"):
        evaluate_cooking(InferenceEngine(store), episodes=0)
    zeros = np.zeros((1, 1, 2))
    empty = CookingResults(("aail",), 0, 5, "x", zeros > 0, zeros, zeros)
    with pytest.raises(ValueError, match="no recorded episode"):
        save_cooking_gif(empty, "unused.gif")


def test_comparison_lines_show_interval_effect_and_holm_p() -> None:
    """Known outcomes, 10 episodes: AAIL serves the right cook's dish in 8 where SL serves it
    in none; its own dish in 9 of SL's 10."""
    served = np.zeros((2, 10, 2), dtype=bool)
    served[0, :9, 0] = True  # AAIL, left cook: 9 of 10
    served[1, :, 0] = True  # SL, left cook: 10 of 10
    served[0, :8, 1] = True  # AAIL, right cook: 8 of 10; SL: 0
    results = CookingResults(
        methods=("aail", "sl"),
        seed=0,
        max_steps=5,
        right_cook="scripted",
        served_MEN=served,
        steps_MEN=np.where(served, 3, -1),
        returns_MEN=served * 20.0,
    )
    [line] = [s for s in results.to_markdown().splitlines() if s.startswith("AAIL - SL:")]
    # left: differences 0 × 9, -1 once: mean -0.10, se 0.10, t_{0.975, 9} = 2.262157;
    # r = -1 (the one discordant pair favours SL); McNemar p = 1 (1 discordant pair)
    # right: 8 discordant pairs, all for AAIL: p = 2 / 2^8 = 0.0078125; Holm over the two: × 2
    left = "left cook -0.10, 95 % CI [-0.33, 0.13], r = -1.00 (McNemar p = 1, Holm p = 1)"
    right = (
        "right cook +0.80, 95 % CI [0.50, 1.10], r = +1.00 (McNemar p = 0.00781, Holm p = 0.0156)"
    )
    assert line == f"AAIL - SL: {left}; {right}."
