"""`coexist eval --suite cooking`: the kitchen experiment of the paper (§4.3-4.4, Fig. 9).

    coexist eval --suite cooking [--store-url URL] [--server URL] [--episodes 100]
                 [--max-steps 400] [--seed 0] [--alias production] [--partner-alias partners]
                 [--out reports/cooking]

In-process by default: the `InferenceEngine` over the model store (`--store-url`, else the
embedded default). With `--server http://host:port` or `grpc://host:port` the episodes go
through a running server instead (the same episodes: common random numbers). The store needs
the cooking zoo (`coexist train zoo --env cooking`: the left cook's task network and the
impact network of CarrotBanana at `--alias`) and, for a learned right cook, a CarrotBanana task
network at `--partner-alias` (without one the scripted cook takes its place, and the results
say so). Writes `results.md`, `results.json`, `fig9_cooking.png` and `aail_episode.gif` into
`--out` and refreshes the cooking section of the paper report beside it
(`evaluation.cooking.report`).
"""

from __future__ import annotations

import shlex
from collections.abc import Callable, Mapping
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import typer

DEFAULT_EPISODES = 100
DEFAULT_MAX_STEPS = 400  # the paper's episode limit in the kitchen


def _command(
    server: str | None, store_url: str | None, out: Path, settings: Mapping[str, Any]
) -> str:
    words = ["coexist", "eval", "--suite", "cooking"]
    words += ["--server", server] if server else []
    words += ["--store-url", store_url] if store_url else []
    for name, value in settings.items():
        words += [f"--{name.replace('_', '-')}", str(value)]
    return shlex.join([*words, "--out", str(out)])


def evaluate_cooking_suite(
    *,
    server: str | None,
    store_url: str | None,
    out: Path | None,
    seed: int,
    episodes: int | None,
    max_steps: int | None,
    alias: str,
    partner_alias: str,
    paper_only: Mapping[str, Any],
) -> None:
    """Run the suite (module docstring); `paper_only` holds the options of the paper suite,
    refused here when given."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    from evaluation.backend import EngineBackend, server_backend
    from evaluation.cooking.report import run_cooking_suite
    from model_store.defaults import open_store
    from services.engine import InferenceEngine

    for name, value in paper_only.items():
        if value not in (None, False, []):
            raise typer.BadParameter(
                "not used by the cooking suite", param_hint=f"--{name.replace('_', '-')}"
            )
    n_episodes, n_steps = episodes or DEFAULT_EPISODES, max_steps or DEFAULT_MAX_STEPS
    settings: dict[str, Any] = {
        "episodes": n_episodes, "max_steps": n_steps, "seed": seed, "alias": alias,
        "partner_alias": partner_alias,
    }  # fmt: skip
    out = out or Path("reports/cooking")
    command = _command(server, store_url, out, settings)
    console = Console()
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[rows]}"))  # fmt: skip
    with ExitStack() as stack:
        if server is None:
            store = stack.enter_context(open_store(store_url))
            backend: Any = EngineBackend(InferenceEngine(store))
        else:
            backend = server_backend(server)
        with Progress(*columns, console=console) as bars:
            task_id = bars.add_task("kitchen steps", total=n_steps, rows="")

            def advance(step: int, running: int) -> None:
                bars.update(task_id, completed=step, rows=f"{running} episodes running")

            progress: Callable[[int, int], None] = advance
            try:
                results, report = run_cooking_suite(
                    backend, out, command=command, progress=progress, **settings
                )
            except LookupError as err:
                console.print(f"[red]{err}[/red]")
                raise typer.Exit(2) from None
    console.print(results.to_markdown())
    console.print(f"results: {out / 'results.md'}" + (f"; updated {report}" if report else ""))
