"""The pairs suite's statistics and report: REPORT.md and results.json.

The unit of analysis is the goal pair: each measure is averaged over a pair's episodes first, so
the intervals speak of goal pairs (n = P), not of correlated episodes.

| measure              | per method                                  | against SL (paired by pair)      |
|----------------------|---------------------------------------------|----------------------------------|
| ego success rate     | mean over pairs, 95 % t interval            | mean difference, 95 % t interval,|
| ego return           |                                             | Wilcoxon p, Holm-adjusted over   |
| team return          |                                             | the methods of that measure      |
| stranded episodes    | SL's ego ends at its goal, the method's not  | (and the converse, "rescued")    |

The default blend's own success against SL's is also tested for non-inferiority: a paired TOST
(`evaluation.stats.tost_paired`) with margin 2 % of SL's success rate, as the paper's report.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.command_line import variables_note
from evaluation.pairs.rollout import Pair, PairEpisodes
from evaluation.stats import fmt_p, holm, paired_ci, tost_paired, wilcoxon_p

MEASURES = {
    "ego_success": "ego success rate",
    "ego_return": "ego return",
    "team_return": "team return",
}
REFERENCE = "sl"
NON_INFERIORITY_MARGIN = 0.02  # a fraction of SL's mean success, the paper's TOST margin


def _per_pair(episodes: PairEpisodes, measure: str) -> np.ndarray:
    values = episodes.team_return if measure == "team_return" else getattr(episodes, measure)
    return np.asarray(values, dtype=np.float64).mean(axis=1)


def summarise(
    results: Sequence[PairEpisodes], pairs: Sequence[Pair], default: str
) -> dict[str, Any]:
    """Every figure of the report, as results.json stores it."""
    by_method = {r.method: r for r in results}
    sl = by_method[REFERENCE]
    methods: dict[str, Any] = {}
    for r in results:
        row: dict[str, Any] = {}
        for measure in MEASURES:
            values = _per_pair(r, measure)
            ci = paired_ci(values, np.zeros_like(values))
            row[measure] = {
                "mean": float(values.mean()),
                "ci95": [ci.low, ci.high],
                "per_pair": values.tolist(),  # in the order of `pairs`
            }
        row["stranded"] = int((sl.ego_success & ~r.ego_success).sum())
        row["rescued"] = int((~sl.ego_success & r.ego_success).sum())
        row["partner_success"] = float(r.partner_success.mean())
        row["episodes"] = int(r.ego_success.size)
        methods[r.method] = row
    versus: dict[str, Any] = {}
    for measure in MEASURES:
        tests: dict[str, dict[str, Any]] = {}
        for r in results:
            if r.method == REFERENCE:
                continue
            a, b = _per_pair(r, measure), _per_pair(sl, measure)
            ci = paired_ci(a, b)
            tests[r.method] = {
                "diff": float((a - b).mean()),
                "ci95": [ci.low, ci.high],
                "p": wilcoxon_p(a, b),
            }
        for name, p in zip(tests, holm([t["p"] for t in tests.values()]), strict=True):
            tests[name]["p_holm"] = p
        versus[measure] = tests
    tost = tost_paired(
        _per_pair(by_method[default], "ego_success"),
        _per_pair(sl, "ego_success"),
        margin_fraction=NON_INFERIORITY_MARGIN,
    )
    return {
        "pairs": [list(p) for p in pairs],
        "default": default,
        "methods": methods,
        "versus_sl": versus,
        "default_success_non_inferiority": {
            "margin": tost.margin,
            "margin_fraction": tost.margin_fraction,
            "diff": tost.diff.mean,
            "ci90": [tost.ci.low, tost.ci.high],
            "p_lower": tost.p_lower,
            "verdict": "not worse" if tost.p_lower < tost.alpha else "not shown",
        },
    }


def _ci(values: Sequence[float], digits: int) -> str:
    low, high = values
    return f"[{low:.{digits}f}, {high:.{digits}f}]" if np.isfinite([low, high]).all() else "—"


def write_report(
    summary: dict[str, Any],
    out: Path,
    *,
    env: str,
    settings: dict[str, Any],
    command: str,
    backend: str,
) -> Path:
    """Write `out`/REPORT.md and `out`/results.json; the report's path."""
    out.mkdir(parents=True, exist_ok=True)
    results = {"env": env, "settings": settings, "command": command, **summary}
    (out / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    default = summary["default"]
    methods = summary["methods"]
    n_pairs = len(summary["pairs"])
    lines = [
        f"# Every method on goal pairs of `{env}`",
        "",
        f"{n_pairs} goal pairs × {settings['pair_episodes']} episodes per method (the same "
        "seeded starts and sampling uniforms for every method); the ego acts by the method with "
        "its partner's goal announced, the partner by its own task network (SL, Boltzmann at its "
        f"training α). Episodes of at most {settings['max_steps']} steps; {backend}. Means over "
        "goal pairs with Student's t 95 % intervals (n = pairs); against SL: paired by pair, "
        "Wilcoxon p with Holm's adjustment over the methods of each measure.",
        "",
        "```console",
        f"$ {command}",
        "```",
        "",
        variables_note(command),
        "",
        "## Per method",
        "",
        "| method | ego success | ego return | team return | partner success | stranded | rescued |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, row in methods.items():
        label = f"**{name}** (default)" if name == default else name
        lines.append(
            f"| {label} | {row['ego_success']['mean']:.3f} {_ci(row['ego_success']['ci95'], 3)}"
            f" | {row['ego_return']['mean']:.2f} {_ci(row['ego_return']['ci95'], 2)}"
            f" | {row['team_return']['mean']:.2f} {_ci(row['team_return']['ci95'], 2)}"
            f" | {row['partner_success']:.3f} | {row['stranded']} | {row['rescued']} |"
        )
    lines += [
        "",
        "Stranded: episodes (of "
        f"{methods[default]['episodes']}) where SL's ego ends at its goal and this method's does "
        "not; rescued: the converse.",
        "",
        "## Against SL (method − SL, paired by goal pair)",
        "",
        "| measure | method | difference | 95 % CI | Wilcoxon p | Holm p |",
        "|---|---|---|---|---|---|",
    ]
    for measure, tests in summary["versus_sl"].items():
        for name, t in tests.items():
            lines.append(
                f"| {MEASURES[measure]} | {name} | {t['diff']:+.3f} | {_ci(t['ci95'], 3)} "
                f"| {fmt_p(t['p'])} | {fmt_p(t['p_holm'])} |"
            )
    ni = summary["default_success_non_inferiority"]
    team = summary["versus_sl"]["team_return"][default]
    lines += [
        "",
        f"## The default ({default}) against SL",
        "",
        f"- Own success: difference {ni['diff']:+.3f}, 90 % interval {_ci(ni['ci90'], 3)}, "
        f"non-inferiority margin −{ni['margin']:.3f} ({ni['margin_fraction']:.0%} of SL's rate): "
        f"p⁻ = {fmt_p(ni['p_lower'])}, **{ni['verdict']}**.",
        f"- Team return: difference {team['diff']:+.2f}, 95 % CI {_ci(team['ci95'], 2)}, "
        f"Holm p = {fmt_p(team['p_holm'])}.",
        "",
        "See `discussion.md` for what these numbers say.",
        "",
    ]
    report = out / "REPORT.md"
    report.write_text("\n".join(lines))
    return report
