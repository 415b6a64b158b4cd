"""`coexist eval --suite partners`: every blending method against partners that are not
coexist's own networks (`evaluation.partner_types`), on goal pairs and five-agent sets drawn
with the run's seed.

    coexist eval --suite partners [--store-url URL] [--server URL] [--seed 0]
                 [--aligned-pairs 12] [--non-aligned-pairs 12] [--pair-episodes 20]
                 [--five-agent-sets 4] [--set-episodes 50] [--max-steps 400]
                 [--alias production] [--partner-alias partners] [--out reports/partners]
                 [--no-goal-oracle] [--no-goal-monitor]

The store needs the particle zoo at `--alias` and a partner population (task networks of
another training seed) at `--partner-alias`: `coexist train task --goals all --seed 1 --alias
partners`. Writes `REPORT.md` and `results.json` into `--out`. `--no-goal-oracle`: the
engine's AAIL-B asks the environment neither whether the ego's goal is reached nor which
actions keep it, as in an environment that cannot tell: AAIL-B asks the ego goal's monitor
(`coexist train monitor`) where one is registered, else R1 on every row; `--no-goal-monitor`:
no monitor either.
"""

from __future__ import annotations

import time
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from evaluation.base import EvalOptions, OptionError, Ui
from evaluation.command_line import portable_command

if TYPE_CHECKING:
    from evaluation.partners.suite import PartnersResult

NOT_USED: tuple[str, ...] = (
    "env",
    "episodes",
    "five_agent_episodes",
    "pairs",
    "timing_log",
    "run_dir",
    "replicates",
    "mixed_pairs",
    "regret_bound",
    "print_combos",
)
SETTINGS: tuple[str, ...] = (
    "aligned_pairs",
    "non_aligned_pairs",
    "pair_episodes",
    "five_agent_sets",
    "set_episodes",
    "max_steps",
)


@dataclass(frozen=True)
class PartnersRun:
    result: PartnersResult
    out: Path
    command: str
    backend: str
    wall_s: float


class PartnersSuite:
    """Every method against every partner type (`evaluation.partners`)."""

    name = "partners"
    help = "(every method against partners that are not coexist's own networks)"

    def run(self, options: EvalOptions, ui: Ui) -> PartnersRun:
        from evaluation.backend import policy_backend
        from evaluation.partners.suite import PartnersConfig, run_partners
        from model_store.defaults import open_store

        for name in NOT_USED:
            if getattr(options, name) not in (None, False, [], ()):
                raise OptionError("not used by the partners suite", f"--{name.replace('_', '-')}")
        given = {k: getattr(options, k) for k in SETTINGS if getattr(options, k) is not None}
        if options.fast:
            given = {
                "aligned_pairs": 1,
                "non_aligned_pairs": 1,
                "pair_episodes": 2,
                "five_agent_sets": 1,
                "set_episodes": 2,
                "max_steps": 30,
                **given,
            }
        if options.partner_types:
            given["partner_types"] = options.partner_types
        try:
            config = PartnersConfig(
                seed=options.seed, alias=options.alias, partner_alias=options.partner_alias, **given
            )
        except ValueError as err:
            raise OptionError(str(err)) from None
        out = options.out or Path("reports/partners")
        with ExitStack() as stack:
            store = None
            if options.server is None:
                store = stack.enter_context(open_store(options.store_url))
            for flag, switched_off in (
                ("--no-goal-oracle", options.no_goal_oracle),
                ("--no-goal-monitor", options.no_goal_monitor),
            ):
                if switched_off and options.server is not None:
                    raise OptionError("needs the in-process engine (a server asks as set)", flag)
            backend = policy_backend(
                options.server,
                store,
                goal_oracle=not options.no_goal_oracle,
                goal_monitors=not options.no_goal_monitor,
            )
            with ui.progress("episodes running") as bars:
                start = time.perf_counter()
                result = run_partners(backend, config, bars)
                wall_s = time.perf_counter() - start
        settings: dict[str, Any] = {k: getattr(config, k) for k in SETTINGS}
        command = _command(options, out, settings)
        return PartnersRun(result, out, command, backend.description, wall_s)

    def write_report(self, run: PartnersRun, options: EvalOptions, ui: Ui) -> None:
        from evaluation.partners.report import write_report
        from services.engine.messages import DEFAULT_METHOD

        report = write_report(
            run.result, run.out, default=DEFAULT_METHOD, command=run.command, backend=run.backend
        )
        ui.print(f"report: {report} ({run.wall_s:.0f} s of episodes)")


PARTNERS_SUITE = PartnersSuite()


def _command(options: EvalOptions, out: Path, settings: dict[str, Any]) -> str:
    """The command line that reproduces this run, every setting spelled out, with no folder of
    the machine it ran on (`evaluation.command_line`)."""
    words = ["coexist", "eval", "--suite", "partners", "--seed", str(options.seed)]
    words += ["--server", options.server] if options.server else []
    words += ["--store-url", options.store_url] if options.store_url else []
    for name, value in settings.items():
        words += [f"--{name.replace('_', '-')}", str(value)]
    words += ["--alias", options.alias, "--partner-alias", options.partner_alias]
    if options.partner_types:
        words += ["--partner-types", ",".join(options.partner_types)]
    if options.no_goal_oracle:
        words.append("--no-goal-oracle")
    if options.no_goal_monitor:
        words.append("--no-goal-monitor")
    return portable_command([*words, "--out", str(out)])
