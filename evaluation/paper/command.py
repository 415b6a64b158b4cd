"""`coexist eval --suite paper`: reproduce the paper's particle experiments and write a report.

    coexist eval --suite paper [--server URL] [--episodes N] [--replicates R] [--seed S]
                 [--aligned-pairs K] [--non-aligned-pairs K] [--mixed-pairs K]
                 [--five-agent-sets K] [--out reports/paper] [--store-url URL] [--fast]

In-process by default: the `InferenceEngine` (the code the servers run) over the model store.
With `--server http://host:port` (REST) or `--server grpc://host:port` the episodes go through a
running server instead; give `--store-url` too for the impact panel of Fig. 6, the training
curves and costs, which read the store. `--fast` runs a few short episodes and, without
`--store-url`, trains a tiny zoo into a temporary store first (its numbers test the harness,
not the paper); its report goes to `reports/paper-fast` unless `--out` says otherwise.
`--print-combos` prints the run's goal combinations (for `coexist train joint --combos`) and
runs nothing.
"""

from __future__ import annotations

from contextlib import AbstractContextManager, ExitStack
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from evaluation.base import EvalOptions, OptionError, Ui, refuse_no_goal_oracle
from evaluation.command_line import portable_command

if TYPE_CHECKING:
    from evaluation.config import Scenario, SuiteConfig
    from evaluation.paper.suite import SuiteResult

# the settings the reproducing command spells out, in its order
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


@dataclass(frozen=True)
class PaperRun:
    """A finished run: its result, where its report goes and the command that reproduces it."""

    result: SuiteResult
    out: Path
    command: str


class PaperSuite:
    """The particle experiments of §4.2 (`evaluation.paper`)."""

    name = "paper"
    help = "(§4.2)"

    def run(self, options: EvalOptions, ui: Ui) -> PaperRun | None:
        refuse_no_goal_oracle(options)
        from evaluation.backend import policy_backend
        from evaluation.paper.suite import run_suite
        from model_store.defaults import open_store

        config = _config(options)
        if options.print_combos:
            print(",".join(dict.fromkeys(s.combo for s in _scenarios(config))))
            return None
        out = options.out or Path("reports/paper-fast" if options.fast else "reports/paper")
        with ExitStack() as stack:
            store = None
            if options.store_url is not None or options.server is None:
                if options.fast and options.store_url is None:
                    ui.print("--fast: training a tiny zoo into a temporary store ...")
                    store = stack.enter_context(_tiny_zoo(config))
                else:
                    store = stack.enter_context(open_store(options.store_url))
            backend = policy_backend(options.server, store)
            with ui.progress("episodes running") as bars:
                result = run_suite(
                    config,
                    backend,
                    store,
                    timing_log=options.timing_log or out / "training_log.jsonl",
                    progress=bars,
                )
        return PaperRun(result, out, _command(config, options, out))

    def write_report(self, run: PaperRun, options: EvalOptions, ui: Ui) -> None:
        from evaluation.paper.report import write_report

        path = write_report(run.result, run.out, command=run.command, run_dirs=[*options.run_dir])
        ui.print(f"report: {path}")


PAPER_SUITE = PaperSuite()


def _config(options: EvalOptions) -> SuiteConfig:
    """The suite's settings: `--fast`'s or the full ones, with the options given."""
    from evaluation.config import SuiteConfig, fast_config

    if options.partner_types:
        raise OptionError("used by --suite partners only", "--partner-types")
    if options.env is not None:
        raise OptionError(
            "used by --suite pairs only (this suite is the particle world's)", "--env"
        )
    if options.pairs is not None:
        raise OptionError(
            "used by --suite inference only; the paper suite draws pairs per class "
            "(--aligned-pairs, --non-aligned-pairs, --mixed-pairs)",
            "--pairs",
        )
    base = fast_config() if options.fast else SuiteConfig()
    names = [n for n in PAPER_COUNTS if n != "seed"] + ["regret_bound"]
    overrides = {n: getattr(options, n) for n in names if getattr(options, n) is not None}
    try:
        return replace(
            base,
            seed=options.seed,
            alias=options.alias,
            partner_alias=options.partner_alias,
            **overrides,
        )
    except ValueError as err:
        raise OptionError(str(err)) from None


def _scenarios(config: SuiteConfig) -> list[Scenario]:
    from evaluation.config import goal_set_scenarios, pair_scenarios, paper_scenarios

    return paper_scenarios(config) + pair_scenarios(config) + goal_set_scenarios(config)


def _tiny_zoo(config: SuiteConfig) -> AbstractContextManager[Any]:
    """A temporary store holding a tiny zoo for the suite's goals (`--fast`)."""
    from evaluation.prepare import tiny_zoo_store

    scenarios = _scenarios(config)
    combos = [s.goals for s in scenarios[:3]] + [s.goals for s in scenarios[3:5]]
    return tiny_zoo_store(
        [s.ego_goal for s in scenarios],
        [g for s in scenarios for g in s.partner_goals],
        combos,
        partner_alias=config.partner_alias,
    )


def _command(config: SuiteConfig, options: EvalOptions, out: Path) -> str:
    """The command line that reproduces this run, every setting spelled out."""
    words = ["coexist", "eval", "--suite", "paper"]
    words += ["--fast"] if config.fast else []
    words += ["--server", options.server] if options.server else []
    words += ["--store-url", options.store_url] if options.store_url else []
    for name in PAPER_COUNTS:
        words += [f"--{name.replace('_', '-')}", str(getattr(config, name))]
    if config.regret_bound is not None:
        words += ["--regret-bound", str(config.regret_bound)]
    words += ["--alias", config.alias, "--partner-alias", config.partner_alias, "--out", str(out)]
    words += ["--timing-log", str(options.timing_log)] if options.timing_log else []
    for run_dir in options.run_dir:
        words += ["--run-dir", str(run_dir)]
    return portable_command(words)
