"""`coexist eval --suite paper`: reproduce the paper's particle experiments and write a report
(`--suite inference`: the online goal-inference experiments, `cli.evaluate_inference`;
`--suite cooking`: the kitchen experiment of Fig. 9, `cli.evaluate_cooking`).

    coexist eval --suite paper [--server URL] [--episodes N] [--replicates R] [--seed S]
                 [--aligned-pairs K] [--non-aligned-pairs K] [--mixed-pairs K]
                 [--five-agent-sets K] [--out reports/paper] [--store-url URL] [--fast]

In-process by default: the `InferenceEngine` (the code the servers run) over the model store.
With `--server http://host:port` (REST) or `--server grpc://host:port` the episodes go through a
running server instead; give `--store-url` too for the impact panel of Fig. 6, the training
curves and costs, which read the store. `--fast` runs a few short episodes and, without
`--store-url`, trains a tiny zoo into a temporary store first (seconds; its numbers test the
harness, not the paper); its report goes to `reports/paper-fast` unless `--out` says otherwise.
"""

from __future__ import annotations

import shlex
import tempfile
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

import typer

ServerOpt = Annotated[
    str | None,
    typer.Option(help="Run episodes through a server: http://host:port or grpc://host:port."),
]
StoreOpt = Annotated[str | None, typer.Option(help="Model store URL (default: embedded SQLite).")]
CountOpt = Annotated[int | None, typer.Option(min=1, help="Default: 200 (--fast: 6).")]
PAPER_COUNTS = (
    "episodes",
    "five_agent_episodes",
    "replicates",
    "aligned_pairs",
    "non_aligned_pairs",
    "mixed_pairs",
    "pair_episodes",
    "five_agent_sets",
    "set_episodes",
    "max_steps",
    "seed",
)
ClassOpt = Annotated[
    int | None,
    typer.Option(min=0, help="Pairs of this strict class drawn per replicate (paper suite)."),
]


def _progress_factory(bars: Any) -> Any:
    def factory(description: str, total: int) -> Any:
        task_id = bars.add_task(description, total=total, rows="")

        def advance(step: int, active: int) -> None:
            bars.update(task_id, completed=step, rows=f"{active} episodes running")

        return advance

    return factory


@contextmanager
def _fast_store(config: Any) -> Iterator[Any]:
    """A temporary store holding a tiny zoo for the suite's goals."""
    from evaluation.config import goal_set_scenarios, pair_scenarios, paper_scenarios
    from evaluation.prepare import train_tiny_zoo
    from model_store.sql import SqlModelStore

    with tempfile.TemporaryDirectory(prefix="coexist-eval-") as tmp:
        store = SqlModelStore(f"sqlite:///{tmp}/models.db")
        scenarios = paper_scenarios(config) + pair_scenarios(config) + goal_set_scenarios(config)
        combos = [s.goals for s in scenarios[:3]] + [s.goals for s in scenarios[3:5]]
        train_tiny_zoo(
            store,
            [s.ego_goal for s in scenarios],
            [g for s in scenarios for g in s.partner_goals],
            combos,
            partner_alias=config.partner_alias,
        )
        try:
            yield store
        finally:
            store.close()


def _command(
    config: Any,
    server: str | None,
    store_url: str | None,
    out: Path,
    log: Path | None,
    run_dirs: list[Path],
) -> str:
    """The command line that reproduces this run, every setting spelled out."""
    words = ["coexist", "eval", "--suite", "paper"]
    words += ["--fast"] if config.fast else []
    words += ["--server", server] if server else []
    words += ["--store-url", store_url] if store_url else []
    for name in PAPER_COUNTS:
        words += [f"--{name.replace('_', '-')}", str(getattr(config, name))]
    if config.regret_bound is not None:
        words += ["--regret-bound", str(config.regret_bound)]
    words += ["--alias", config.alias, "--partner-alias", config.partner_alias, "--out", str(out)]
    words += ["--timing-log", str(log)] if log else []
    for run_dir in run_dirs:
        words += ["--run-dir", str(run_dir)]
    return shlex.join(words)


def evaluate(
    suite: Annotated[
        str,
        typer.Option(
            help="'paper' (§4.2), 'inference' (online goal inference) or 'cooking' (Fig. 9)."
        ),
    ] = "paper",
    server: ServerOpt = None,
    episodes: CountOpt = None,
    five_agent_episodes: Annotated[
        int | None, typer.Option(min=1, help="Default: 100 (--fast: 4).")
    ] = None,
    pairs: Annotated[
        int | None,
        typer.Option(min=0, help="--suite inference: sampled goal pairs. Default: 100."),
    ] = None,
    replicates: Annotated[
        int | None,
        typer.Option(
            min=1,
            help="Replicates (seeds seed, seed+1, ...), each drawing its own "
            "pairs, goal sets and starts. Default: 3 (--fast: 1).",
        ),
    ] = None,
    aligned_pairs: ClassOpt = None,
    non_aligned_pairs: ClassOpt = None,
    mixed_pairs: ClassOpt = None,
    five_agent_sets: Annotated[
        int | None, typer.Option(min=0, help="Five-agent goal sets per replicate. Default: 8.")
    ] = None,
    set_episodes: Annotated[
        int | None, typer.Option(min=1, help="Episodes per goal set. Default: 100.")
    ] = None,
    regret_bound: Annotated[
        float | None,
        typer.Option(min=0.0, help="AAIL-B's ε (default: half the task network's training α)."),
    ] = None,
    pair_episodes: Annotated[
        int | None, typer.Option(min=1, help="Episodes per pair. Default: 20 (--fast: 3).")
    ] = None,
    max_steps: Annotated[
        int | None, typer.Option(min=1, help="Episode limit. Default: 400 (--fast: 40).")
    ] = None,
    seed: Annotated[int, typer.Option(min=0, help="Seed of starts, pairs and sampling.")] = 0,
    out: Annotated[Path | None, typer.Option(help="Report folder.")] = None,
    store_url: StoreOpt = None,
    timing_log: Annotated[
        Path | None,
        typer.Option(help="Training wall-time log (default: OUT/training_log.jsonl)."),
    ] = None,
    run_dir: Annotated[
        list[Path] | None,
        typer.Option(help="Training run directory whose curves_*.png go into Fig. 4 (repeat)."),
    ] = None,
    alias: Annotated[str, typer.Option(help="Alias of the controlled agent's networks.")] = (
        "production"
    ),
    partner_alias: Annotated[str, typer.Option(help="Alias of the partner population.")] = (
        "partners"
    ),
    fast: Annotated[bool, typer.Option(help="A few short episodes (tests the harness).")] = False,
    print_combos: Annotated[
        bool,
        typer.Option(
            help="Print the goal combinations of this run, comma-separated (for "
            "`coexist train joint --combos`), and exit."
        ),
    ] = False,
) -> None:
    """Run the paper's experiments (§4.2) and write REPORT.md with tables, plots and verdicts."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    from evaluation.backend import EngineBackend, server_backend
    from evaluation.config import SuiteConfig, fast_config
    from evaluation.paper.report import write_report
    from evaluation.paper.suite import run_suite
    from model_store.defaults import open_store
    from services.engine import InferenceEngine

    if suite == "inference":
        from cli.evaluate_inference import evaluate_inference

        evaluate_inference(
            server=server, store_url=store_url, out=out, seed=seed, fast=fast, episodes=episodes,
            pairs=pairs, pair_episodes=pair_episodes, max_steps=max_steps, alias=alias,
            partner_alias=partner_alias,
        )  # fmt: skip
        return
    if suite == "cooking":
        from cli.evaluate_cooking import evaluate_cooking_suite

        paper_only = {"five_agent_episodes": five_agent_episodes, "pairs": pairs,
                      "pair_episodes": pair_episodes, "timing_log": timing_log,
                      "run_dir": run_dir, "fast": fast, "replicates": replicates,
                      "aligned_pairs": aligned_pairs, "non_aligned_pairs": non_aligned_pairs,
                      "mixed_pairs": mixed_pairs, "five_agent_sets": five_agent_sets,
                      "set_episodes": set_episodes, "regret_bound": regret_bound}  # fmt: skip
        evaluate_cooking_suite(
            server=server, store_url=store_url, out=out, seed=seed, episodes=episodes,
            max_steps=max_steps, alias=alias, partner_alias=partner_alias, paper_only=paper_only,
        )  # fmt: skip
        return
    if suite != "paper":
        raise typer.BadParameter(
            f"unknown suite {suite!r}; expected 'paper', 'inference' or 'cooking'",
            param_hint="--suite",
        )
    if pairs is not None:
        raise typer.BadParameter(
            "used by --suite inference only; the paper suite draws pairs per class "
            "(--aligned-pairs, --non-aligned-pairs, --mixed-pairs)",
            param_hint="--pairs",
        )
    base = fast_config() if fast else SuiteConfig()
    overrides: dict[str, Any] = {
        "episodes": episodes, "five_agent_episodes": five_agent_episodes,
        "replicates": replicates, "aligned_pairs": aligned_pairs,
        "non_aligned_pairs": non_aligned_pairs, "mixed_pairs": mixed_pairs,
        "pair_episodes": pair_episodes, "five_agent_sets": five_agent_sets,
        "set_episodes": set_episodes, "max_steps": max_steps, "regret_bound": regret_bound,
    }  # fmt: skip
    try:
        config = replace(
            base,
            seed=seed,
            alias=alias,
            partner_alias=partner_alias,
            **{k: v for k, v in overrides.items() if v is not None},
        )
    except ValueError as err:
        raise typer.BadParameter(str(err)) from None
    if print_combos:
        from evaluation.config import goal_set_scenarios, pair_scenarios, paper_scenarios

        scenarios = paper_scenarios(config) + pair_scenarios(config) + goal_set_scenarios(config)
        print(",".join(dict.fromkeys(s.combo for s in scenarios)))
        return
    out = out or Path("reports/paper-fast" if fast else "reports/paper")
    console = Console()
    with ExitStack() as stack:
        store = None
        if store_url is not None or server is None:
            if fast and store_url is None:
                console.print("--fast: training a tiny zoo into a temporary store ...")
                store = stack.enter_context(_fast_store(config))
            else:
                store = stack.enter_context(open_store(store_url))
        if server is None:
            assert store is not None
            backend: Any = EngineBackend(InferenceEngine(store))
        else:
            backend = server_backend(server)
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("{task.fields[rows]}"))  # fmt: skip
        with Progress(*columns, console=console) as bars:
            try:
                result = run_suite(
                    config,
                    backend,
                    store,
                    timing_log=timing_log or out / "training_log.jsonl",
                    progress=_progress_factory(bars),
                )
            except LookupError as err:
                console.print(f"[red]{err}[/red]")
                raise typer.Exit(2) from None
    command = _command(config, server, store_url, out, timing_log, run_dir or [])
    path = write_report(result, out, command=command, run_dirs=run_dir or [])
    console.print(f"report: {path}")
