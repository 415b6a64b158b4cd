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
(`evaluation.cooking.report`). The paper suite's own options are refused.
"""

from __future__ import annotations

import time
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from evaluation.base import EvalOptions, OptionError, Ui, refuse_no_goal_oracle
from evaluation.command_line import portable_command

if TYPE_CHECKING:
    from evaluation.cooking.suite import CookingResults

DEFAULT_EPISODES = 100
DEFAULT_MAX_STEPS = 400  # the paper's episode limit in the kitchen
# options of the paper suite that this one refuses, in the order they are checked
PAPER_ONLY = (
    "env",
    "five_agent_episodes",
    "pairs",
    "pair_episodes",
    "timing_log",
    "run_dir",
    "fast",
    "replicates",
    "aligned_pairs",
    "non_aligned_pairs",
    "mixed_pairs",
    "five_agent_sets",
    "set_episodes",
    "regret_bound",
    "partner_types",
)


@dataclass(frozen=True)
class CookingRun:
    """A finished run: the results, how they were made and where the report goes."""

    results: CookingResults
    out: Path
    command: str
    backend: str
    wall_s: float


class CookingSuite:
    """The kitchen experiment of Fig. 9 (`evaluation.cooking`)."""

    name = "cooking"
    help = "(Fig. 9)"

    def run(self, options: EvalOptions, ui: Ui) -> CookingRun:
        refuse_no_goal_oracle(options)
        from evaluation.backend import policy_backend
        from evaluation.cooking.suite import evaluate_cooking
        from model_store.defaults import open_store

        for name in PAPER_ONLY:
            if getattr(options, name) not in (None, False, [], ()):
                raise OptionError("not used by the cooking suite", f"--{name.replace('_', '-')}")
        settings: dict[str, Any] = {
            "episodes": options.episodes or DEFAULT_EPISODES,
            "max_steps": options.max_steps or DEFAULT_MAX_STEPS,
            "seed": options.seed,
            "alias": options.alias,
            "partner_alias": options.partner_alias,
        }
        out = options.out or Path("reports/cooking")
        with ExitStack() as stack:
            store = None
            if options.server is None:
                store = stack.enter_context(open_store(options.store_url))
            backend = policy_backend(options.server, store)
            with ui.progress("episodes running") as bars:
                start = time.perf_counter()
                results = evaluate_cooking(
                    backend, progress=bars("kitchen steps", settings["max_steps"]), **settings
                )
                wall_s = time.perf_counter() - start
        command = _command(options.server, options.store_url, out, settings)
        return CookingRun(results, out, command, backend.description, wall_s)

    def write_report(self, run: CookingRun, options: EvalOptions, ui: Ui) -> None:
        from evaluation.cooking.report import write_cooking_report

        report = write_cooking_report(
            run.results, run.out, command=run.command, backend=run.backend, wall_s=run.wall_s
        )
        ui.print(run.results.to_markdown())
        ui.print(f"results: {run.out / 'results.md'}" + (f"; updated {report}" if report else ""))


COOKING_SUITE = CookingSuite()


def _command(server: str | None, store_url: str | None, out: Path, settings: dict[str, Any]) -> str:
    """The command line that reproduces this run, every setting spelled out."""
    words = ["coexist", "eval", "--suite", "cooking"]
    words += ["--server", server] if server else []
    words += ["--store-url", store_url] if store_url else []
    for name, value in settings.items():
        words += [f"--{name.replace('_', '-')}", str(value)]
    return portable_command([*words, "--out", str(out)])
