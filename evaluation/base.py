"""What an evaluation suite implements, and what it is given.

`coexist eval --suite NAME` parses every option once into `EvalOptions`, looks the suite up
(`evaluation.suites.get_suite`: the `coexist.suites` entry points) and calls its `run`, then its
`write_report`. Each suite lives in its own folder (`evaluation/<suite>/command.py`, or a
plugin's package), reads the options it uses (and refuses, with an `OptionError`, those it
cannot honour), and shows progress through the `Ui` the CLI gives it. So adding a suite (a
third environment's experiments) means adding its module and one entry point; the CLI tests no
suite's name.

A suite's module imports its heavy parts (torch, the engine, matplotlib) inside `run` and
`write_report`: the CLI imports every suite to build `--help`, which stays fast.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TypeVar

Advance = Callable[[int, int], None]
"""A progress bar's callback: (steps done, how many episodes are still running)."""
Bars = Callable[[str, int], Advance]
"""(label, total steps) -> a new progress bar's callback."""


@dataclass(frozen=True)
class EvalOptions:
    """Every option of `coexist eval` as the user gave it (None: not given; each suite has its
    own defaults and says which options it uses in its `--help` text)."""

    server: str | None = None
    store_url: str | None = None
    out: Path | None = None
    seed: int = 0
    fast: bool = False
    episodes: int | None = None
    five_agent_episodes: int | None = None
    pairs: int | None = None
    replicates: int | None = None
    aligned_pairs: int | None = None
    non_aligned_pairs: int | None = None
    mixed_pairs: int | None = None
    five_agent_sets: int | None = None
    set_episodes: int | None = None
    pair_episodes: int | None = None
    max_steps: int | None = None
    regret_bound: float | None = None
    timing_log: Path | None = None
    run_dir: tuple[Path, ...] = ()
    alias: str = "production"
    partner_alias: str = "partners"
    print_combos: bool = False
    partner_types: tuple[str, ...] = ()  # the partners suite's partner types (empty: all)
    env: str | None = None  # the pairs suite's environment (any registered one)
    no_goal_oracle: bool = False  # the partners suite: AAIL-B without the environment's answers
    no_goal_monitor: bool = False  # the partners suite: AAIL-B without goal monitors


class OptionError(ValueError):
    """An option the suite cannot take, or a value it refuses; `option` names it (`--pairs`),
    None where the message names the setting itself."""

    def __init__(self, message: str, option: str | None = None) -> None:
        super().__init__(message)
        self.option = option


def refuse_no_goal_oracle(options: EvalOptions) -> None:
    """`--no-goal-oracle` and `--no-goal-monitor` are the partners suite's: another suite would
    ignore them silently."""
    if options.no_goal_oracle:
        raise OptionError("--suite partners only", "--no-goal-oracle")
    if options.no_goal_monitor:
        raise OptionError("--suite partners only", "--no-goal-monitor")


class Ui(Protocol):
    """What a suite shows while it runs (the CLI's console)."""

    def print(self, text: str) -> None: ...

    def progress(self, unit: str) -> AbstractContextManager[Bars]:
        """Progress bars for the block it opens, each showing its count followed by `unit`
        ("episodes running"). A `LookupError` raised in the block (a network the store does
        not serve) ends the command with its message."""
        ...


Run = TypeVar("Run")


class Suite(Protocol[Run]):
    """One `coexist eval --suite NAME`: its experiments (`run`) and its report."""

    name: str
    """The `--suite` value."""
    help: str
    """What `--help` says after the name: the paper's section or figure it reproduces."""

    def run(self, options: EvalOptions, ui: Ui) -> Run | None:
        """Run the experiments; what `write_report` needs, or None when there is nothing to
        report (the options only asked for information). OptionError for a refused option."""
        ...

    def write_report(self, run: Run, options: EvalOptions, ui: Ui) -> None:
        """Write the report's files (into `options.out`, else the suite's own folder under
        `reports/`) and say where they are."""
        ...
