"""`coexist eval --suite inference`: online goal inference, its accuracy and value (issue 9).

    coexist eval --suite inference --store-url URL [--episodes N] [--pairs K] [--out DIR]
    coexist eval --suite inference --fast          # a tiny zoo in a temporary store (seconds)

In-process only (the likelihood pass is the engine's; no `--server`). The store needs all 35
task and impact networks at `--alias` and the 35 task networks of the partner population at
`--partner-alias`. Writes `results.json`, the figures and `README.md` into `--out` (default
`reports/inference`, `reports/inference-fast` with `--fast`); `benchmarks/session_bench.py`
adds the latency section to the same README.
"""

from __future__ import annotations

import shlex
import tempfile
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import typer


@contextmanager
def _fast_store(partner_alias: str) -> Iterator[Any]:
    """A temporary store with a tiny zoo for every goal (task, impact, partner population)."""
    from envs.particle.goals import GOAL_IDS
    from evaluation.prepare import train_tiny_zoo
    from model_store.sql import SqlModelStore

    with tempfile.TemporaryDirectory(prefix="coexist-inference-") as tmp:
        store = SqlModelStore(f"sqlite:///{tmp}/models.db")
        train_tiny_zoo(store, GOAL_IDS, GOAL_IDS, [], partner_alias=partner_alias)
        try:
            yield store
        finally:
            store.close()


def _command(config: Any, store_url: str | None, out: Path) -> str:
    value = config.value
    words = ["coexist", "eval", "--suite", "inference"] + (["--fast"] if config.fast else [])
    words += ["--store-url", store_url] if store_url else []
    words += ["--episodes", str(value.episodes), "--pairs", str(value.pairs)]
    words += ["--pair-episodes", str(value.pair_episodes), "--max-steps", str(value.max_steps)]
    words += ["--seed", str(value.seed), "--alias", value.alias]
    words += ["--partner-alias", value.partner_alias, "--out", str(out)]
    return shlex.join(words)


def evaluate_inference(
    *,
    server: str | None,
    store_url: str | None,
    out: Path | None,
    seed: int,
    fast: bool,
    episodes: int | None,
    pairs: int | None,
    pair_episodes: int | None,
    max_steps: int | None,
    alias: str,
    partner_alias: str,
) -> None:
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    from evaluation.inference.report import render_readme
    from evaluation.inference.suite import (
        InferenceSuiteConfig,
        fast_inference_config,
        run_inference_suite,
        write_results,
    )
    from model_store.defaults import open_store
    from services.engine import InferenceEngine

    if server is not None:
        raise typer.BadParameter(
            "the inference suite runs in-process (the likelihood pass is the engine's); "
            "give --store-url instead",
            param_hint="--server",
        )
    base = fast_inference_config(seed) if fast else InferenceSuiteConfig()
    v = base.value
    try:
        config = replace(
            base,
            accuracy=replace(base.accuracy, alias=alias, partner_alias=partner_alias, seed=seed),
            value=replace(
                v, alias=alias, partner_alias=partner_alias, seed=seed,
                episodes=episodes or v.episodes, pairs=v.pairs if pairs is None else pairs,
                pair_episodes=pair_episodes or v.pair_episodes, max_steps=max_steps or v.max_steps,
            ),
        )  # fmt: skip
    except ValueError as err:
        raise typer.BadParameter(str(err)) from None
    out = out or Path("reports/inference-fast" if fast else "reports/inference")
    console = Console()
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[rows]}"))  # fmt: skip
    with ExitStack() as stack:
        if fast and store_url is None:
            console.print("--fast: training a tiny zoo into a temporary store ...")
            store = stack.enter_context(_fast_store(partner_alias))
        else:
            store = stack.enter_context(open_store(store_url))
        engine = InferenceEngine(store)
        with Progress(*columns, console=console) as bars:

            def factory(label: str, total: int) -> Callable[[int, int], None]:
                task_id = bars.add_task(label, total=total, rows="")
                return lambda step, n: bars.update(task_id, completed=step, rows=f"{n}")

            try:
                results = run_inference_suite(
                    engine, store, config, command=_command(config, store_url, out),
                    progress=factory,
                )  # fmt: skip
            except LookupError as err:
                console.print(f"[red]{err}[/red]")
                raise typer.Exit(2) from None
    write_results(results, out)
    console.print(f"report: {render_readme(out)}")
