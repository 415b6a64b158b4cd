"""`coexist eval --suite NAME`: run one evaluation suite and write its report.

The suites (`evaluation.suites`, plugins: `paper`, the particle experiments of §4.2; `inference`,
online goal inference; `cooking`, the kitchen of Fig. 9) each read the options they use from
`evaluation.base.EvalOptions`; their modules' docstrings (`evaluation/<suite>/command.py`) say
which and what each writes. This module only parses the options and gives the suite a console.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer

from evaluation.base import Bars, EvalOptions, OptionError
from evaluation.suites import DEFAULT_SUITE, get_suite, suites_help
from model_store.errors import InvalidArgument

ServerOpt = Annotated[
    str | None,
    typer.Option(help="Run episodes through a server: http://host:port or grpc://host:port."),
]
StoreOpt = Annotated[str | None, typer.Option(help="Model store URL (default: embedded SQLite).")]
CountOpt = Annotated[int | None, typer.Option(min=1, help="Default: 200 (--fast: 6).")]
ClassOpt = Annotated[
    int | None,
    typer.Option(min=0, help="Pairs of this strict class drawn per replicate (paper suite)."),
]


class _ConsoleUi:
    """`evaluation.base.Ui` on a rich console: progress bars with a count column."""

    def __init__(self) -> None:
        from rich.console import Console

        self.console = Console()

    def print(self, text: str) -> None:
        self.console.print(text)

    @contextmanager
    def progress(self, unit: str) -> Iterator[Bars]:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

        columns = (
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[rows]}"),
        )
        with Progress(*columns, console=self.console) as bars:

            def bar(label: str, total: int) -> Callable[[int, int], None]:
                task_id = bars.add_task(label, total=total, rows="")

                def advance(step: int, count: int) -> None:
                    bars.update(task_id, completed=step, rows=f"{count} {unit}".rstrip())

                return advance

            try:
                yield bar
            except LookupError as err:  # a network the store does not serve
                self.console.print(f"[red]{err}[/red]")
                raise typer.Exit(2) from None


def evaluate(
    suite: Annotated[str, typer.Option(help=suites_help())] = DEFAULT_SUITE,
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
        typer.Option(min=0.0, help="AAIL-B's ε (default: twice the task network's training α)."),
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
    partner_types: Annotated[
        str | None,
        typer.Option(
            help="--suite partners: comma-separated partner types (evaluation/partner_types.py). "
            "Default: all."
        ),
    ] = None,
    env: Annotated[
        str | None,
        typer.Option(
            help="--suite pairs: the environment (any registered one: `coexist env list`)."
        ),
    ] = None,
    no_goal_oracle: Annotated[
        bool,
        typer.Option(
            "--no-goal-oracle",
            help="--suite partners: AAIL-B asks the environment neither whether the ego's goal "
            "is reached nor which actions keep it (its goal monitors answer where registered).",
        ),
    ] = False,
    no_goal_monitor: Annotated[
        bool,
        typer.Option(
            "--no-goal-monitor",
            help="--suite partners: AAIL-B asks no goal monitor (`coexist train monitor`) "
            "where the environment does not answer.",
        ),
    ] = False,
    print_combos: Annotated[
        bool,
        typer.Option(
            help="Print the goal combinations of this run, comma-separated (for "
            "`coexist train joint --combos`), and exit."
        ),
    ] = False,
) -> None:
    """Run the paper's experiments (§4.2) and write REPORT.md with tables, plots and verdicts."""
    try:
        chosen = get_suite(suite)
    except ValueError as err:
        raise typer.BadParameter(str(err), param_hint="--suite") from None
    options = EvalOptions(
        server=server,
        store_url=store_url,
        out=out,
        seed=seed,
        fast=fast,
        episodes=episodes,
        five_agent_episodes=five_agent_episodes,
        pairs=pairs,
        replicates=replicates,
        aligned_pairs=aligned_pairs,
        non_aligned_pairs=non_aligned_pairs,
        mixed_pairs=mixed_pairs,
        five_agent_sets=five_agent_sets,
        set_episodes=set_episodes,
        pair_episodes=pair_episodes,
        max_steps=max_steps,
        regret_bound=regret_bound,
        timing_log=timing_log,
        run_dir=tuple(run_dir or ()),
        alias=alias,
        partner_alias=partner_alias,
        print_combos=print_combos,
        partner_types=tuple(t.strip() for t in (partner_types or "").split(",") if t.strip()),
        env=env,
        no_goal_oracle=no_goal_oracle,
        no_goal_monitor=no_goal_monitor,
    )
    ui = _ConsoleUi()
    try:
        run = chosen.run(options, ui)
    except OptionError as err:
        raise typer.BadParameter(str(err), param_hint=err.option) from None
    except InvalidArgument as err:  # a store URL that names no store (or a missing driver)
        ui.console.print(f"[red]error:[/red] {err}")
        raise typer.Exit(2) from None
    if run is not None:
        chosen.write_report(run, options, ui)
