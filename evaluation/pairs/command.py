"""`coexist eval --suite pairs --env NAME`: every method on goal pairs of any registered
environment (`evaluation.pairs.rollout`, `evaluation.pairs.report`).

    coexist eval --suite pairs --env NAME [--store-url URL] [--server URL] [--seed 0]
                 [--pairs P] [--pair-episodes 20] [--max-steps 100] [--regret-bound ε]
                 [--alias production] [--out reports/NAME]

The store needs the environment's zoo at `--alias` (`coexist train zoo --env NAME`): a task
and an impact network per goal. `--pairs` draws that many ordered goal pairs with the seed
(default: every ordered pair of distinct goals). Writes `REPORT.md` and `results.json` into
`--out`; a hand-written `discussion.md` beside them is left as it is.
"""

from __future__ import annotations

import time
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from evaluation.base import EvalOptions, OptionError, Ui, refuse_no_goal_oracle
from evaluation.command_line import portable_command

METHODS = ("sl", "nail", "aail", "aail_bounded", "aail_budget")
USED = {"server", "store_url", "out", "seed", "fast", "pairs", "pair_episodes", "max_steps"}
USED |= {"regret_bound", "alias", "env", "partner_alias"}  # partner_alias: its default is ignored
DEFAULT_EPISODES, DEFAULT_MAX_STEPS = 20, 100
FAST_PAIRS, FAST_EPISODES, FAST_MAX_STEPS = 2, 2, 20


@dataclass(frozen=True)
class PairsRun:
    env: str
    summary: dict[str, Any]
    settings: dict[str, Any]
    out: Path
    command: str
    backend: str
    wall_s: float


class PairsSuite:
    """Every method on goal pairs of a plugin environment."""

    name = "pairs"
    help = "(every method on goal pairs of any environment: needs --env)"

    def run(self, options: EvalOptions, ui: Ui) -> PairsRun:
        refuse_no_goal_oracle(options)
        from envs.registry import env_plugin
        from evaluation.backend import policy_backend
        from evaluation.pairs.report import summarise
        from evaluation.pairs.rollout import goal_pairs, run_method
        from model_store.defaults import open_store
        from services.engine.messages import DEFAULT_METHOD

        for name, value in vars(options).items():
            if name not in USED and value not in (None, False, (), [], 0):
                raise OptionError("not used by the pairs suite", f"--{name.replace('_', '-')}")
        if options.env is None:
            raise OptionError("the pairs suite needs an environment", "--env")
        try:
            domain = env_plugin(options.env).domain
        except ValueError as err:
            raise OptionError(str(err), "--env") from None
        if len(domain.goals) < 2 or domain.max_agents < 2:
            raise OptionError(f"{options.env!r} cannot host two agents on distinct goals", "--env")
        fast = options.fast
        settings: dict[str, Any] = {
            "pairs": options.pairs if options.pairs is not None else (FAST_PAIRS if fast else None),
            "pair_episodes": options.pair_episodes or (FAST_EPISODES if fast else DEFAULT_EPISODES),
            "max_steps": options.max_steps or (FAST_MAX_STEPS if fast else DEFAULT_MAX_STEPS),
            "regret_bound": options.regret_bound,
        }
        if settings["pairs"] == 0:
            raise OptionError("expected at least one pair", "--pairs")
        pairs = goal_pairs(domain.goals, settings["pairs"], options.seed)
        out = options.out or Path("reports") / options.env
        with ExitStack() as stack:
            store = None
            if options.server is None:
                store = stack.enter_context(open_store(options.store_url))
            backend = policy_backend(options.server, store)
            results = []
            start = time.perf_counter()
            with ui.progress("episodes running") as bars:
                for method in METHODS:
                    results.append(
                        run_method(
                            backend,
                            options.env,
                            pairs,
                            method,
                            episodes=settings["pair_episodes"],
                            seed=options.seed,
                            max_steps=settings["max_steps"],
                            alias=options.alias,
                            regret_bound=settings["regret_bound"],
                            advance=bars(method, settings["max_steps"]),
                        )
                    )
            wall_s = time.perf_counter() - start
        summary = summarise(results, pairs, DEFAULT_METHOD)
        command = _command(options, out, settings)
        return PairsRun(options.env, summary, settings, out, command, backend.description, wall_s)

    def write_report(self, run: PairsRun, options: EvalOptions, ui: Ui) -> None:
        from evaluation.pairs.report import write_report

        report = write_report(
            run.summary,
            run.out,
            env=run.env,
            settings=run.settings,
            command=run.command,
            backend=run.backend,
        )
        ui.print(f"report: {report} ({run.wall_s:.0f} s of episodes)")


PAIRS_SUITE = PairsSuite()


def _command(options: EvalOptions, out: Path, settings: dict[str, Any]) -> str:
    """The command line that reproduces this run, every setting spelled out, with no folder of
    the machine it ran on (`evaluation.command_line`)."""
    words = ["coexist", "eval", "--suite", "pairs", "--env", str(options.env)]
    words += ["--seed", str(options.seed)]
    words += ["--server", options.server] if options.server else []
    words += ["--store-url", options.store_url] if options.store_url else []
    for name, value in settings.items():
        if value is not None:
            words += [f"--{name.replace('_', '-')}", str(value)]
    words += ["--alias", options.alias]
    return portable_command([*words, "--out", str(out)])
