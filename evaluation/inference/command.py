"""`coexist eval --suite inference`: online goal inference, its accuracy and value.

    coexist eval --suite inference --store-url URL [--episodes N] [--pairs K] [--out DIR]
    coexist eval --suite inference --fast          # a tiny zoo in a temporary store

In-process only (the likelihood pass is the engine's; no `--server`). The store needs all 35
task and impact networks at `--alias` and the 35 task networks of the partner population at
`--partner-alias`. Writes `results.json`, the figures and `README.md` into `--out` (default
`reports/inference`, `reports/inference-fast` with `--fast`); `benchmarks/session_bench.py`
adds the latency section to the same README. The paper suite's other options are ignored.
"""

from __future__ import annotations

from contextlib import AbstractContextManager, ExitStack
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from evaluation.base import EvalOptions, OptionError, Ui, refuse_no_goal_oracle
from evaluation.command_line import portable_command

if TYPE_CHECKING:
    from evaluation.inference.suite import InferenceSuiteConfig


@dataclass(frozen=True)
class InferenceRun:
    """A finished run: everything `results.json` holds, and where the report goes."""

    results: dict[str, Any]
    out: Path


class InferenceSuite:
    """The goal-inference experiments (`evaluation.inference`)."""

    name = "inference"
    help = "(online goal inference)"

    def run(self, options: EvalOptions, ui: Ui) -> InferenceRun:
        refuse_no_goal_oracle(options)
        from evaluation.inference.suite import run_inference_suite
        from model_store.defaults import open_store
        from services.engine import InferenceEngine

        if options.partner_types:
            raise OptionError("used by --suite partners only", "--partner-types")
        if options.env is not None:
            raise OptionError("used by --suite pairs only", "--env")
        if options.server is not None:
            raise OptionError(
                "the inference suite runs in-process (the likelihood pass is the engine's); "
                "give --store-url instead",
                "--server",
            )
        config = _config(options)
        out = options.out or Path("reports/inference-fast" if options.fast else "reports/inference")
        with ExitStack() as stack:
            if options.fast and options.store_url is None:
                ui.print("--fast: training a tiny zoo into a temporary store ...")
                store = stack.enter_context(_tiny_zoo(options.partner_alias))
            else:
                store = stack.enter_context(open_store(options.store_url))
            engine = InferenceEngine(store)
            with ui.progress("") as bars:
                results = run_inference_suite(
                    engine,
                    store,
                    config,
                    command=_command(config, options.store_url, out),
                    progress=bars,
                )
        return InferenceRun(results, out)

    def write_report(self, run: InferenceRun, options: EvalOptions, ui: Ui) -> None:
        from evaluation.inference.report import render_readme
        from evaluation.inference.suite import write_results

        write_results(run.results, run.out)
        ui.print(f"report: {render_readme(run.out)}")


INFERENCE_SUITE = InferenceSuite()


def _config(options: EvalOptions) -> InferenceSuiteConfig:
    """`--fast`'s or the full settings, with the options given."""
    from evaluation.inference.suite import InferenceSuiteConfig, fast_inference_config

    base = fast_inference_config(options.seed) if options.fast else InferenceSuiteConfig()
    v, o = base.value, options
    try:
        return replace(
            base,
            accuracy=replace(
                base.accuracy, alias=o.alias, partner_alias=o.partner_alias, seed=o.seed
            ),
            value=replace(
                v,
                alias=o.alias,
                partner_alias=o.partner_alias,
                seed=o.seed,
                episodes=o.episodes or v.episodes,
                pairs=v.pairs if o.pairs is None else o.pairs,
                pair_episodes=o.pair_episodes or v.pair_episodes,
                max_steps=o.max_steps or v.max_steps,
            ),
        )
    except ValueError as err:
        raise OptionError(str(err)) from None


def _tiny_zoo(partner_alias: str) -> AbstractContextManager[Any]:
    """A temporary store with a tiny zoo for every goal (task, impact, partner population)."""
    from envs.particle.goals import GOAL_IDS
    from evaluation.prepare import tiny_zoo_store

    return tiny_zoo_store(GOAL_IDS, GOAL_IDS, [], partner_alias=partner_alias)


def _command(config: InferenceSuiteConfig, store_url: str | None, out: Path) -> str:
    """The command line that reproduces this run, every setting spelled out."""
    value = config.value
    words = ["coexist", "eval", "--suite", "inference"] + (["--fast"] if config.fast else [])
    words += ["--store-url", store_url] if store_url else []
    words += ["--episodes", str(value.episodes), "--pairs", str(value.pairs)]
    words += ["--pair-episodes", str(value.pair_episodes), "--max-steps", str(value.max_steps)]
    words += ["--seed", str(value.seed), "--alias", value.alias]
    words += ["--partner-alias", value.partner_alias, "--out", str(out)]
    return portable_command(words)
