"""`reports/inference/README.md` and its figures, drawn from the JSON files next to it.

| file                 | written by                                   | content                       |
|----------------------|----------------------------------------------|-------------------------------|
| `results.json`       | `coexist eval --suite inference`             | accuracy, switch, value       |
| `latency.json`       | `benchmarks/session_bench.py`                | session step vs act latency   |
| `calibration.json`   | `python -m evaluation.inference.calibration` | how the likelihood was chosen |
| `discussion.md`      | a person, after reading the numbers          | copied into the README        |
| `README.md`          | `render_readme(out)` (both commands call it) | tables, verdicts, figures     |
| `accuracy_vs_k.png`, `cross_entropy.png`, `goal_switch.png`, `value.png` | `render_readme` | |

Everything but the discussion is computed from the JSON, so either command can re-render the
whole README without the other's run. `paper_section` is the short summary that
`evaluation.paper.report` puts into the paper report, linking here.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from evaluation.command_line import variables_note
from evaluation.inference.calibration import CALIBRATION, calibration_table
from evaluation.inference.plots import (
    plot_accuracy,
    plot_cross_entropy,
    plot_switch,
    plot_value,
)
from evaluation.inference.suite import REPORT_KS
from evaluation.inference.tables import (
    LATENCY_TARGET,
    blend_text,
    latency_section,
    main_table,
    networks_table,
    recovered_text,
    settings_table,
    switch_table,
    value_block,
)
from evaluation.paper.tables import table
from services.engine.goal_inference import LIKELIHOOD_TEMPERING

DISCUSSION = "discussion.md"


def _load(path: Path) -> dict[str, Any] | None:
    return json.loads(path.read_text()) if path.exists() else None


def _accuracy_section(results: dict[str, Any], out: Path) -> str:
    acc, switch, matched = results["accuracy"], results["switch"], results.get("matched")
    cfg = acc["config"]
    reference = next(iter(matched["series"].values())) if matched else None
    plot_accuracy(acc["series"], acc["episodes"], out / "accuracy_vs_k.png", reference)
    plot_cross_entropy(acc["series"], out / "cross_entropy.png")
    plot_switch(
        switch["series"], switch["episodes"], switch["config"]["switch_at"], out / "goal_switch.png"
    )
    confusions = [[t, g, str(n)] for t, g, n in acc["confusions"]]
    k = acc["confusions_at_k"]
    sw = switch["config"]["switch_at"]
    default = next(iter(acc["series"]))
    lines = [
        f"{acc['episodes']} episodes ({cfg['episodes_per_goal']} per true goal × 35 goals), "
        f"{cfg['k_max']} steps each, seed {cfg['seed']}, {acc['wall_s']:.0f} s. The first "
        f"setting, the server's default ({default}; α: {LIKELIHOOD_TEMPERING:g} × each task "
        "network's training α, `LIKELIHOOD_TEMPERING`; η: the likelihood's uniform action "
        "noise, `DEFAULT_NOISE`), drives "
        f"the ego, which blends impact networks by {blend_text(cfg)}; the others are tracked on "
        "the same trajectories. Top-1 with its Wilson 95 % interval; top-3: the true goal among the three most likely; *up to nesting*: the top "
        "goal is the true goal or its target area contains, or lies inside, the true one (a "
        "cell and its row or column: the same behaviour once the partner is there); "
        "cross-entropy -log b_k(g*) in nats, mean ± SE (uniform: log 35 = 3.56).",
        "",
        main_table(acc),
        "",
        "![accuracy vs k](accuracy_vs_k.png)",
        "",
        "![cross-entropy vs k](cross_entropy.png)",
        "",
        "Every belief setting (the last row: the default belief when the partner acts by the "
        "very networks that score it, `partner_alias` = `alias`):",
        "",
        settings_table(acc, matched),
        "",
        f"Most frequent errors of the default belief at k = {k} (true goal, the belief's top "
        "goal, episodes):",
        "",
        table(["true goal", "top goal", "episodes"], confusions) if confusions else "none",
        "",
        f"### The partner changes its goal at k = {sw}",
        "",
        f"The same setup, but after {sw} steps the partner's goal moves to another goal "
        "(seeded) and it acts by that goal's task policy from then on; accuracy against the "
        "*current* goal.",
        "",
        switch_table(switch),
        "",
        "![goal switch](goal_switch.png)",
    ]
    if results.get("partners"):
        lines += ["", partners_section(results["partners"])]
    calibration = _load(out / CALIBRATION)
    if calibration is not None:
        lines += ["", calibration_section(calibration)]
    return "\n".join(lines)


def calibration_section(calibration: dict[str, Any]) -> str:
    """How the default likelihood was chosen (`evaluation.inference.calibration`)."""
    best = calibration["candidates"][calibration["best"]]
    verdict = (
        "it beats the likelihood of before on the calibration types and is not below it "
        "with `same`: adopted as the default"
        if calibration["adopted"]
        else "it does not beat the likelihood of before on the calibration types, or it is "
        "below it with `same`: not adopted"
    )
    return "\n".join(
        [
            "### Choosing the likelihood on the calibration types",
            "",
            f"Command: `{calibration['command']}`"
            + (
                f" ({variables_note(calibration['command']).rstrip('.')})"
                if "$" in calibration["command"]
                else ""
            )
            + ". p(a | s, g) = (1 − η) softmax(Q_g(s, ·) / α)[a] + η / |A|, α a multiple of "
            f"the task networks' training α ({calibration['training_alpha']:g}). Top-3 after "
            f"{calibration['k']} actions, {calibration['episodes']} episodes per partner type "
            f"(seed {calibration['seed']}, not the suite's), every candidate on the same "
            "trajectories (the ego driven by the first row); the candidate with the best mean "
            "over the calibration types is adopted only if it beats the first row there and is "
            "not below it with `same` (coexist's own networks, a guard, not a calibration type). "
            "The scored types are not run here.",
            "",
            calibration_table(calibration),
            "",
            f"Best: {best['tempering']:g} × α, η = {best['noise']:g}; {verdict}.",
        ]
    )


def partners_section(partners: dict[str, Any]) -> str:
    """The default belief against every partner type, and the bar: top-3 within 5 points of the
    accuracy against coexist's own networks, for the types that did not choose the tempering."""
    own = partners.get("same")
    rows = []
    for name, p in partners.items():
        gap = "" if own is None else f"{100 * (p['top3'] - own['top3']):+.1f}"
        role = "calibration" if p["calibration"] else "scored"
        verdict = (
            ""
            if p["calibration"] or own is None
            else ("✔" if p["top3"] >= own["top3"] - 0.05 else "✘")
        )
        rows.append(
            [name, role, str(p["episodes"]), f"{p['top1']:.3f}", f"{p['top3']:.3f}", gap, verdict]
        )
    k = next(iter(partners.values()))["k"]
    return "\n".join(
        [
            f"### Partners who are not coexist (`evaluation/partner_types.py`), k = {k}",
            "",
            "The default belief when the partner acts as each type says (its goal fixed). The "
            "likelihood's tempering (`LIKELIHOOD_TEMPERING` in `services/engine/goal_inference.py`) "
            "and its uniform action noise (`DEFAULT_NOISE` in `policy/belief.py`) were chosen on "
            "the calibration types (below); the bar (top-3 within 5 points of the accuracy "
            "against coexist's own networks, `same`) is judged on the others.",
            "",
            table(
                [
                    "partner type",
                    "role",
                    "episodes",
                    "top-1",
                    "top-3",
                    "top-3 − same (points)",
                    "bar",
                ],
                rows,
            ),
        ]
    )


def _value_section(results: dict[str, Any], out: Path) -> str:
    value = results["value"]
    cfg = value["config"]
    blocks = [(k.replace("_", "-"), c, "episodes") for k, c in value["scenarios"].items()]
    blocks += [(k, c, "pairs") for k, c in value["pair_groups"].items()]
    panels = {
        f"{label} ({c['units']} {unit})": {
            m: {k: (v[0], v[1]) for k, v in by.items()} for m, by in c["means"].items()
        }
        for label, c, unit in blocks
    }
    plot_value(panels, out / "value.png")
    walls = ", ".join(f"{k} {v:.0f} s" for k, v in value["wall_s"].items())
    lines = [
        f"The paper suite's two-agent scenarios ({cfg['episodes']} episodes each) and its sample "
        f"of {cfg['pairs']} goal pairs × {cfg['pair_episodes']} episodes, same start seeds, "
        f"episodes up to {cfg['max_steps']} steps; belief: forgetting "
        f"{cfg['belief']['forgetting']}, floor {cfg['belief']['floor']}, uniform prior; the "
        f"ego blends impact networks by {blend_text(cfg)}. "
        f"Paired (same starts and random numbers for every method). Wall time: {walls}.",
        "",
        *(value_block(label, c, unit) + "\n" for label, c, unit in blocks),
        "![value](value.png)",
    ]
    return "\n".join(lines)


def render_readme(out: Path) -> Path:
    """README.md and its figures from `results.json` / `latency.json` in `out` (either may be
    missing); returns the README's path."""
    out.mkdir(parents=True, exist_ok=True)
    results, latency = _load(out / "results.json"), _load(out / "latency.json")
    discussion_file = out / DISCUSSION
    discussion = (
        discussion_file.read_text().strip()
        if discussion_file.exists()
        else f"*Not written yet: put the discussion in `{DISCUSSION}` and re-run.*"
    )
    fast = results is not None and results.get("fast")
    parts = [
        "# Online goal inference: accuracy, value, latency"
        + (" (**--fast: tiny networks, numbers test the harness only**)" if fast else ""),
        "Partners who do not announce their goals: the server keeps a belief over each "
        "partner's goal, P(g | history) ∝ P(g) Π_t π_g(a_t | s_t), the partner's 35 task "
        "networks as Boltzmann likelihoods (`policy/belief.py`, "
        "`services/engine/goal_inference.py`), and AAIL blends the impact networks by it. "
        "Everything below is computed (`evaluation/inference*.py`, `benchmarks/session_bench.py`) "
        f"except the discussion (`{DISCUSSION}`).",
    ]
    if results is not None:
        parts += [
            "## Setup",
            f"- Command: `{results['command']}`"
            f"{' (' + variables_note(results['command']).rstrip('.') + ')' if '$' in results['command'] else ''}.",
            "- The partner acts by its true goal's task policy softmax(Q/α) from the "
            f"**`{results['accuracy']['config']['partner_alias']}` population**, trained with "
            "another seed; the belief scores its actions with the "
            f"**`{results['accuracy']['config']['alias']}`** task networks, so the likelihood "
            "networks did not generate the behaviour. The ego acts with AAIL through the engine, "
            "its partner given by the belief (`blend_goal_probs`), as a session step does.\n",
            networks_table(results),
            "## Accuracy: does the belief find the goal?",
            _accuracy_section(results, out),
            "## Value: AAIL with inferred goals vs announced goals and SL",
            _value_section(results, out),
        ]
    parts += ["## Latency: a session step vs a plain act", latency_section(latency)]
    parts += ["## Discussion", discussion]
    path = out / "README.md"
    path.write_text("\n\n".join(parts) + "\n")
    return path


def paper_section(paper_out: Path) -> str:
    """The paper report's short section on goal inference, linking `../inference/README.md`
    (read from `paper_out/../inference/results.json` and `latency.json` when present)."""
    folder = paper_out.resolve().parent / "inference"
    results, latency = _load(folder / "results.json"), _load(folder / "latency.json")
    link = "[`reports/inference/README.md`](../inference/README.md)"
    if results is None:
        return f"Not run yet (`coexist eval --suite inference`); the report goes to {link}."
    lines = [f"Partners who do not announce their goals; the full report is {link}."]
    series = results["accuracy"]["series"]
    first = next(iter(series))
    acc, top3 = series[first]["accuracy"], series[first]["top3"]
    ks = [k for k in REPORT_KS if k < len(acc)]
    lines.append(
        f"- The belief's top goal is the partner's true goal ({first}, "
        f"{results['accuracy']['episodes']} episodes): "
        + ", ".join(f"k = {k}: {acc[k]:.2f}" for k in ks)
        + f"; the true goal among the top three at k = {ks[-1]}: {top3[ks[-1]]:.2f}."
    )
    for label, c in results["value"]["scenarios"].items():
        means, gap = c["means"], c["diffs"]["team: aail − sl"]["mean"]
        share = (
            "inference keeps {} of the announced goal's gain"
            if gap > 0
            else "announcing lowers it, and the inferred ego incurs {} of that loss"
        )
        lines.append(
            f"- {label.replace('_', '-')} scenario, team return: SL {means['sl']['team'][0]:.2f}, "
            f"AAIL announced {means['aail']['team'][0]:.2f}, AAIL inferred "
            f"{means['aail-inferred']['team'][0]:.2f}; "
            + share.format(recovered_text(c["recovered"]))
            + "."
        )
    if latency is not None:
        shown = {k: v for k, v in latency["ratios"].items() if "top-8" not in k}
        lines.append(
            "- Latency, REST session step p50 / plain act p50: "
            + ", ".join(f"{k} {v:.2f}×" for k, v in shown.items())
            + f" (target <= {LATENCY_TARGET})."
        )
    return "\n".join(lines)
