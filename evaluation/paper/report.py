"""`REPORT.md`, its figures and `results.json` from a `SuiteResult`.

Everything in the report is computed here from the results; the only hand-written part is the
discussion, kept in `discussion.md` next to the report and copied in (a placeholder when absent),
so re-running the evaluation never loses it.

| file                      | content                                                    |
|---------------------------|------------------------------------------------------------|
| `REPORT.md`               | verdicts per claim, setup, tables, figures, models, discussion, |
|                           | and a summary of the goal-inference report (`../inference/`)    |
|                           | and of the cooking experiment (`../cooking/`, `evaluation.cooking.report`) |
| `results.json`            | every episode's numbers per scenario and method            |
| `fig5_two_agents.png`     | Fig. 5: aligned and non-aligned returns                    |
| `fig7_five_agents.png`    | Fig. 7: five-agent returns                                 |
| `fig_pairs.png`           | goal pairs per strict class and five-agent goal sets       |
| `fig6_directions.png`     | Fig. 6: expected acceleration, non-aligned scenario        |
| `fig4_training.png`       | Fig. 4 from the lineage curve summaries                    |
| `episode_strip.png`       | one non-aligned episode per method                         |
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path

from evaluation.command_line import variables_note
from evaluation.cooking.report import COOKING_HEADING, cooking_section
from evaluation.inference.report import paper_section
from evaluation.paper import plots
from evaluation.paper.claims import (
    EQUIVALENCE_MARGIN,
    Claim,
    claim_aligned,
    claim_five,
    claim_non_aligned,
    claim_scaling,
    scenario_family,
)
from evaluation.paper.directions import box_centre
from evaluation.paper.pairs import UnitGroup, class_family, pair_groups, replicate_rows
from evaluation.paper.suite import SuiteResult, results_json
from evaluation.paper.tables import (
    fmt_ms,
    label,
    models_table,
    replicate_table,
    scaling_table,
    summary_table,
    table,
    targets_table,
    tests_table,
    training_table,
    unit_rows_table,
    unit_tests_table,
    worst_units_table,
)
from evaluation.stats import CI_LEVEL, summarise_cell
from evaluation.targets import TEAM_MARGIN, Target, targets_of
from policy.regret_bound import DEFAULT_EPSILON_PER_ALPHA

DISCUSSION = "discussion.md"
SECTIONS = (
    "## Verdicts",
    "## Setup",
    "## Goal-aligned scenario",
    "## Non-aligned scenario",
    "## Five agents",
    "## Goal pairs nobody tuned on",
    "## Direction of acceleration",
    "## Training and scaling",
    "## Episode strip",
    "## Models used",
    "## Discussion",
    "## Online goal inference",
    COOKING_HEADING,
)
FIGURE_NAMES = {
    "aligned": "Fig. 5 left",
    "non_aligned": "Fig. 5 right",
    "five_agents": "Fig. 7",
}


def claims_of(result: SuiteResult) -> list[Claim]:
    """The paper's claims 1-4, judged on its scenarios (for the paper-exact AAIL)."""
    return [
        claim_aligned(result.cells["aligned"]),
        claim_non_aligned(result.cells["non_aligned"]),
        claim_five(result.cells["five_agents"]),
        claim_scaling(result.training),
    ]


BLENDS = ("aail_bounded", "aail")  # judged by the targets, the server's default first


def _targets(result: SuiteResult) -> list[Target]:
    methods = tuple(m for m in BLENDS if m in result.config.methods)
    return targets_of(pair_groups(result.pair_results), methods)


def _verdicts(claims: list[Claim]) -> str:
    rows = [
        [
            c.key,
            c.title,
            c.paper or "(generalisation, not in the paper)",
            "<br>".join(ch.detail for ch in c.checks),
            f"**{c.verdict}**",
        ]
        for c in claims
    ]
    lines = [table(["claim", "what", "paper", "this project", "verdict"], rows), ""]
    lines += [
        "The paper's claims are judged on its own scenarios with the paper-exact AAIL; what the "
        "product promises on goal pairs nobody tuned on is judged below them (targets T1-T3, "
        "`evaluation.targets`), for AAIL-B (the server's default) and for AAIL.",
        "",
    ]
    for c in claims:
        lines.append(f"**Claim {c.key}: {c.title}** — {c.verdict}.")
        lines += [f"- {'✔' if ch.passed else '✘'} {ch.text}: {ch.detail}" for ch in c.checks]
        failed = [ch.text.split(" (")[0] for ch in c.checks if not ch.passed]
        if failed:
            lines.append(
                f"- *Differs from the paper:* {'; '.join(failed)} — not found here (numbers "
                "above; the discussion says why)."
            )
        lines.append("")
    return "\n".join(lines)


def _note(command: str) -> str:
    note = variables_note(command)
    return f" ({note})" if note else ""


def _setup(result: SuiteResult, command: str) -> str:
    cfg = result.config
    rows = [
        [
            s.name,
            s.ego_goal,
            " ".join(s.partner_goals),
            s.pair_class or "-",
            str(s.episodes),
            str(s.start_seed),
            "yes" if result.jl_available[s.name] else "no",
        ]
        for s in result.scenarios
    ]
    units = sorted({r.scenario for r in result.pair_results}, key=lambda s: s.start_seed)
    pairs = [s for s in units if s.n_agents == 2]
    sets = [s for s in units if s.n_agents != 2]
    count = {
        k: len({s.combo for s in pairs if s.pair_class == k})
        for k in ("aligned", "non_aligned", "mixed")
    }
    with_jl = len({s.combo for s in units if result.jl_available[s.name]})
    bound = (
        f"the engine's default ({DEFAULT_EPSILON_PER_ALPHA:g} × the task network's α)"
        if cfg.regret_bound is None
        else f"{cfg.regret_bound:g}"
    )
    walls = ", ".join(f"{k} {v:.1f} s" for k, v in result.wall_s.items())
    return "\n".join(
        [
            f"- Command: `{command}`" + _note(command),
            f"- Backend: {result.backend}; {result.backend_calls:,} policy calls; wall time: {walls}.",
            f"- Seed {cfg.seed}; episodes end when every agent is inside its target at one step or "
            f"after **{cfg.max_steps} steps** (the paper: 1000). Controlled agent (agent 1 in the "
            f"figures) uses the `{cfg.alias}` networks; partners act with the task networks of the "
            f"`{cfg.partner_alias}` population (another seed), sampling their Boltzmann policy.",
            "- Paired episodes: every method faces the same start states and the same uniform "
            "random numbers for its action sampling (common random numbers).",
            "- *ego success*: the ego ends the episode inside its target; *ego reached*: it was "
            "inside at some step; *solved*: the episode ended by the env's termination.",
            f"- Goal pairs nobody tuned on: {cfg.replicates} replicates (seeds {cfg.seed}.."
            f"{cfg.seed + cfg.replicates - 1}), each drawing up to {cfg.aligned_pairs} aligned, "
            f"{cfg.non_aligned_pairs} non-aligned and {cfg.mixed_pairs} mixed pairs and "
            f"{cfg.five_agent_sets} five-agent goal sets, with its own starts: "
            f"{count['aligned']} aligned, {count['non_aligned']} non-aligned and "
            f"{count['mixed']} mixed distinct pairs × {cfg.pair_episodes} episodes per "
            f"replicate, {len(sets)} goal sets × {cfg.set_episodes} episodes; JL where a joint "
            f"network was trained ({with_jl} of them). AAIL-B's regret bound ε: {bound}. The "
            "pairs and sets of every replicate are in `results.json`.",
            _statistics_note(),
            "",
            table(["scenario", "ego", "partners", "class", "episodes", "start seed", "JL"], rows),
        ]
    )


def _statistics_note() -> str:
    return (
        f"- Statistics (`evaluation.stats`): beside every p, the mean paired difference ± SE, its "
        f"{CI_LEVEL:.0%} Student t interval and the matched-pairs rank-biserial correlation r "
        "(−1..1, over the same non-zero differences the Wilcoxon test ranks; for success, "
        "(b − c) / (b + c) over McNemar's discordant pairs). p's are two-sided; *p (Holm)* is "
        "Holm's step-down adjustment within its family: each scenario's table of paired tests, "
        "each pair class's table of tests over pairs, and T1's non-inferiority tests over the "
        "methods judged; every verdict reads the adjusted p. Claims of *not worse* or *the same* "
        "are paired TOST equivalence tests (two one-sided t tests), never a large p: team "
        f"return not below SL's with a margin of {TEAM_MARGIN:.0%} of SL's mean (T1), AAIL ≈ "
        f"NAIL with a margin of {EQUIVALENCE_MARGIN:.0%} of NAIL's mean (claim 1); both "
        "one-sided p's are printed (p⁻: worse by the margin or more; p⁺: better by it or more)."
    )


def _scenario_section(result: SuiteResult, name: str, figure: str) -> str:
    cells = result.cells[name]
    summaries = [summarise_cell(cells[m]) for m in cells]
    ranked = sorted(summaries, key=lambda s: -s.team.mean)
    lines = [
        summary_table(summaries),
        "",
        "Paired tests over the episodes (Δ = first − second; this table is one family for Holm's "
        "correction):",
        "",
        tests_table(scenario_family(cells)),
        "",
        "Ranking by team return: "
        + " > ".join(f"{label(s.method)} ({fmt_ms(s.team)})" for s in ranked)
        + ".",
    ]
    if name == "five_agents":
        rows = [[label(s.method)] + [fmt_ms(p) for p in s.per_partner] for s in summaries]
        partners = result.cells[name]["aail"].scenario.partner_goals
        lines += ["", "Each partner's return:", "", table(["method", *partners], rows)]
    lines += ["", f"![{FIGURE_NAMES[name]}]({figure})"]
    return "\n".join(lines)


def _group_section(group: UnitGroup, heading: str) -> list[str]:
    return [
        heading,
        "",
        "Means over pairs of the per-pair means (each pair pooled over its replicates):",
        "",
        unit_rows_table(group),
        "",
        "Paired tests over pairs (this table is one family for Holm's correction):",
        "",
        unit_tests_table(class_family(group)),
        "",
        "Where AAIL-B and AAIL strand the ego most often (then the largest own-return regret):",
        "",
        worst_units_table(group, BLENDS),
        "",
    ]


def _pairs_section(result: SuiteResult, figure: str | None) -> str:
    groups = pair_groups(result.pair_results)
    if not groups:
        return "No goal pair or goal set was drawn (every count 0)."
    targets = _targets(result)
    lines = [
        "Pairs are classified strictly by the ego's target area T and the partner's influence "
        "area I (`envs.particle.scenarios.pair_class`): *aligned*, I inside T (*room to help*: "
        "T strictly contains I); *non-aligned*, T and I do not touch; *mixed*, the rest. A "
        "*stuck* episode ends with the ego outside its target: it never reached it, or left it "
        "and did not come back, and every agent paid for every step up to the limit.",
        "",
        targets_table(targets),
        "",
    ]
    headings = {
        "aligned": "### Aligned pairs",
        "room_to_help": "### Aligned pairs with room to help",
        "non_aligned": "### Non-aligned pairs",
        "mixed": "### Mixed pairs",
        "five_agents": "### Five agents, random goal sets",
    }
    for key, group in groups.items():
        lines += _group_section(group, f"{headings[key]} ({len(group.units)})")
    rows = replicate_rows(result.pair_results, result.config.seed)
    lines += [
        "### Per replicate",
        "",
        "Each replicate draws its own pairs and starts with its own "
        "seed; a result that holds in one replicate only would show here.",
        "",
        replicate_table(rows, ("sl", *BLENDS)),
        "",
    ]
    if figure:
        lines.append(f"![goal pairs]({figure})")
    return "\n".join(lines)


def _figures(result: SuiteResult, out: Path) -> dict[str, str]:
    made = {}
    two = [
        (result.cells[n]["aail"].scenario, [summarise_cell(c) for c in result.cells[n].values()])
        for n in ("aligned", "non_aligned")
    ]
    made["two"] = plots.plot_returns(two, out / "fig5_two_agents.png", "Fig. 5").name
    five = result.cells["five_agents"]
    panel = [(five["aail"].scenario, [summarise_cell(c) for c in five.values()])]
    made["five"] = plots.plot_returns(panel, out / "fig7_five_agents.png", "Fig. 7").name
    groups = pair_groups(result.pair_results)
    if groups:
        made["pairs"] = plots.plot_pairs(list(groups.values()), out / "fig_pairs.png").name
    scenario = result.cells["non_aligned"]["aail"].scenario
    partner = scenario.partner_goals[0]
    made["fields"] = plots.plot_directions(
        result.fields, scenario.ego_goal, partner, box_centre(partner), out / "fig6_directions.png"
    ).name
    if result.curves:
        made["curves"] = plots.plot_training(result.curves, out / "fig4_training.png").name
    strips = {m: c.trajectory_TN4 for m, c in result.cells["non_aligned"].items()}
    made["strip"] = plots.plot_episode_strip(strips, scenario.goals, out / "episode_strip.png").name
    return made


def _models_section(result: SuiteResult) -> str:
    failed = sorted(f"`{n}` v{v}" for (n, v), g in result.gates.items() if g == "failed")
    note = (
        "Versions whose quality gate failed (they serve because an operator promoted them; see "
        "the discussion): " + ", ".join(failed) + "."
        if failed
        else "Every version used passed its quality gate (or has none: --fast)."
    )
    if not result.gates:
        note = "Gate verdicts need the store (`--store-url`); not available for this run."
    return models_table(result.models, result.gates) + "\n\n" + note


def copy_run_curves(run_dirs: Sequence[Path], out: Path) -> list[str]:
    """Copy the trainer's own curve plots (`curves_{kind}.png`, the full training curves) from
    training run directories into `out`; returns the copied file names."""
    copied = []
    for run_dir in run_dirs:
        for source in sorted(run_dir.glob("curves_*.png")):
            name = f"fig4_{run_dir.name}_{source.stem.removeprefix('curves_')}.png"
            shutil.copyfile(source, out / name)
            copied.append(name)
    return copied


def _training_section(
    result: SuiteResult, figures: dict[str, str], run_curves: Sequence[str]
) -> str:
    lines = ["Networks needed to cover every goal combination (|G| = 35):", "", scaling_table(), ""]
    if result.training:
        lines += [
            "What one network cost to train (lineage configs; wall time from the timing "
            "log, `evaluation.timing`):",
            "",
            training_table(result.training),
            "",
        ]
    else:
        lines.append("No model store was given, so training costs are not reported.")
    if "curves" in figures:
        lines += [
            "Fig. 4 is drawn from the **lineage curve summaries** of the registered "
            "versions (first and final logged mean training return per network; the full "
            "curves are not stored), over every registered network of each kind:",
            "",
            f"![Fig. 4]({figures['curves']})",
        ]
    if run_curves:
        lines += [
            "",
            "The full training curves, as the trainer plotted them in its run directories "
            "(`--run-dir`; mean ± std over the networks trained together):",
            "",
        ]
        lines += [f"![{name}]({name})" for name in run_curves]
    return "\n".join(lines)


def write_report(
    result: SuiteResult, out: Path, *, command: str, run_dirs: Sequence[Path] = ()
) -> Path:
    """Write REPORT.md, the figures and results.json into `out`; returns the report's path."""
    out.mkdir(parents=True, exist_ok=True)
    figures = _figures(result, out)
    run_curves = copy_run_curves(run_dirs, out)
    claims = claims_of(result)
    discussion_file = out / DISCUSSION
    discussion = (
        discussion_file.read_text().strip()
        if discussion_file.exists()
        else f"*Not written yet: put the discussion in `{DISCUSSION}` and re-run.*"
    )
    fast = (
        " (**--fast: tiny networks and few episodes; these numbers test the harness, not the paper**)"
        if result.config.fast
        else ""
    )
    parts = [
        f"# Reproducing the paper's particle experiments (§4.1-4.2){fast}",
        f"Generated by `coexist eval` on {datetime.now(UTC):%Y-%m-%d %H:%M} UTC from the results "
        f"of the command below; every number and verdict is computed (`evaluation/`), only the "
        f"discussion is hand-written (`{DISCUSSION}`).",
        SECTIONS[0],
        _verdicts(claims),
        SECTIONS[1],
        _setup(result, command),
        SECTIONS[2] + " (ego `c`, partner `c4`; paper Fig. 5 left)",
        _scenario_section(result, "aligned", figures["two"]),
        SECTIONS[3] + " (ego `a2`, partner `b3`; paper Fig. 5 right)",
        _scenario_section(result, "non_aligned", figures["two"]),
        SECTIONS[4] + " (ego `a2`, partners `a0 b2 c4 e1`; paper Fig. 7)",
        _scenario_section(result, "five_agents", figures["five"]),
        SECTIONS[5],
        _pairs_section(result, figures.get("pairs")),
        SECTIONS[6] + " (paper Fig. 6, non-aligned scenario)",
        "Expected acceleration Σ_a π(a) d_a over a 15 × 15 grid of ego positions at rest, the "
        "partner at rest at the centre of its target area (red dot).\n\n"
        f"![Fig. 6]({figures['fields']})",
        SECTIONS[7],
        _training_section(result, figures, run_curves),
        SECTIONS[8] + " (non-aligned scenario, episode 0)",
        f"![episode strip]({figures['strip']})",
        SECTIONS[9],
        _models_section(result),
        SECTIONS[10],
        discussion,
        SECTIONS[11],
        paper_section(out),  # from reports/inference/*.json (`coexist eval --suite inference`)
        cooking_section(out.parent / "cooking", out),  # `coexist eval --suite cooking`
    ]
    path = out / "REPORT.md"
    path.write_text("\n\n".join(parts) + "\n")
    (out / "results.json").write_text(json.dumps(results_json(result)))
    return path
