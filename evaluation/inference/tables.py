"""Markdown tables of the goal-inference report, built from `results.json` / `latency.json`
(`evaluation.inference.report` assembles them; nothing here is typed by hand).

| function          | rows                                                                 |
|-------------------|----------------------------------------------------------------------|
| `main_table`      | the server's default belief and λ = 1: every measure at k = 0 and the |
|                   | report's k values                                                    |
| `settings_table`  | every belief setting (and the matched run): top-1 over k, the rest   |
|                   | at the last k                                                        |
| `switch_table`    | top-1 around the partner's change of goal                            |
| `value_block`     | one scenario or pair group: returns, paired tests, recovered share   |
| `latency_section` | the benchmark's cases, ratios and in-process breakdown               |
| `networks_table`  | the populations the runs used, with seeds and gate verdicts          |
"""

from __future__ import annotations

from typing import Any

from envs.particle.goals import N_GOALS
from evaluation.inference.plots import VALUE_LABELS
from evaluation.inference.suite import REPORT_KS
from evaluation.paper.tables import fmt_p, table

LATENCY_TARGET = 1.5  # session step p50 / plain act p50, the latency target


def report_ks(acc: dict[str, Any]) -> list[int]:
    return [k for k in REPORT_KS if k <= acc["config"]["k_max"]]


def main_table(acc: dict[str, Any]) -> str:
    """The first two settings (the server's default and λ = 1), every measure, k = 0 and the
    report's k values."""
    ks = [0, *report_ks(acc)]
    rows = []
    for label, s in list(acc["series"].items())[:2]:
        rows += [
            [
                label,
                "top-1 [95 % CI]",
                *(
                    f"{s['accuracy'][k]:.2f} [{s['accuracy_lo'][k]:.2f}, {s['accuracy_hi'][k]:.2f}]"
                    for k in ks
                ),
            ],
            [label, "top-3", *(f"{s['top3'][k]:.2f}" for k in ks)],
            [label, "top-1 up to nesting", *(f"{s['nested'][k]:.2f}" for k in ks)],
            [
                label,
                "cross-entropy (nats)",
                *(f"{s['cross_entropy'][k]:.2f} ± {s['cross_entropy_se'][k]:.2f}" for k in ks),
            ],
        ]
    return table(["belief", "measure", *(f"k = {k}" for k in ks)], rows)


def settings_table(acc: dict[str, Any], matched: dict[str, Any] | None) -> str:
    """One row per belief setting (and the matched run): top-1 over k, the rest at the end."""
    ks, end = report_ks(acc), acc["config"]["k_max"]
    runs = [(label, s) for label, s in acc["series"].items()]
    if matched is not None:
        label, s = next(iter(matched["series"].items()))
        runs.append((f"{label}, partner driven by the likelihood nets", s))
    rows = [
        [
            label,
            *(f"{s['accuracy'][k]:.2f}" for k in ks),
            f"{s['top3'][end]:.2f}",
            f"{s['nested'][end]:.2f}",
            f"{s['cross_entropy'][end]:.2f}",
        ]
        for label, s in runs
    ]
    header = [
        "belief",
        *(f"top-1, k = {k}" for k in ks),
        f"top-3, k = {end}",
        f"nested, k = {end}",
        f"cross-entropy, k = {end}",
    ]
    return table(header, rows)


def switch_table(switch: dict[str, Any]) -> str:
    sw, end = switch["config"]["switch_at"], switch["config"]["k_max"]
    ks = sorted({sw, *(k for k in (sw + 1, sw + 5, sw + 10) if k < end), end})
    rows = [
        [label, *(f"{s['accuracy'][k]:.2f}" for k in ks), f"{s['cross_entropy'][end]:.2f}"]
        for label, s in switch["series"].items()
    ]
    header = ["belief", *(f"top-1, k = {k}" for k in ks), f"cross-entropy, k = {end}"]
    return table(header, rows)


def blend_text(cfg: dict[str, Any]) -> str:
    """How the runs blended impact networks by the belief (a session's blend settings)."""
    mass, most = cfg.get("blend_mass", 0.99), cfg.get("blend_max_goals", 8)
    if mass >= 1 and (most is None or most >= N_GOALS):
        return "the whole belief (all 35 goals)"
    cap = "" if most is None else f", at most {most}"
    return f"its top goals covering {mass:g} of its mass{cap}"


def mean_se_text(pair: list[float]) -> str:
    return f"{pair[0]:.2f} ± {pair[1]:.2f}"


def recovered_text(triple: list[float | None]) -> str:
    point, lo, hi = triple
    if point is None:
        return "undefined (announced and SL tie)"
    interval = "" if lo is None or hi is None else f" [{lo:.2f}, {hi:.2f}]"
    return f"{point:.2f}{interval}"


def value_block(label: str, c: dict[str, Any], unit: str) -> str:
    rows = [
        [
            VALUE_LABELS[m],
            *(mean_se_text(by[k]) for k in ("team", "ego", "others")),
            f"{c['ego_success'][m]:.2f}",
        ]
        for m, by in c["means"].items()
    ]
    tests = [
        [
            name.replace("aail-inferred", "inferred").replace("aail", "announced"),
            f"{d['mean']:.2f} ± {d['se']:.2f}",
            fmt_p(d["p"]),
        ]
        for name, d in c["diffs"].items()
    ]
    gap = c["diffs"]["team: aail − sl"]
    recovered = (
        f"**Recovered** (team return, (inferred − SL) / (announced − SL)): "
        f"{recovered_text(c['recovered'])} (bootstrap 95 %, over {c['units']} {unit}); the "
        f"announced − SL gap itself is {gap['mean']:.2f} ± {gap['se']:.2f} "
        f"(p = {fmt_p(gap['p'])})."
    )
    if gap["p"] >= 0.05:
        recovered += " That gap is not significant, so the ratio means little here."
    elif gap["mean"] < 0:
        recovered += (
            " Announcing the goal *lowers* the team return here (AAIL below SL), so the ratio "
            "is the share of that loss the inferred ego still incurs: lower is better."
        )
    top1 = c.get("belief_top1_at_end")
    lines = [
        f"### {label} ({c['units']} {unit})",
        "",
        table(["ego", "team return", "ego return", "partner return", "ego success"], rows),
        "",
        table(["paired difference", "mean ± SE", "Wilcoxon p"], tests),
        "",
        recovered,
    ]
    if top1 is not None:
        lines += [
            "",
            f"The belief's top goal was the partner's goal at the end of {top1:.0%} of "
            "the inferred episodes.",
        ]
    return "\n".join(lines)


def latency_section(latency: dict[str, Any] | None) -> str:
    if latency is None:
        return "Not measured yet: run `benchmarks/session_bench.py` (it re-renders this file)."
    rows = [
        [
            c["case"],
            f"{c['p50_ms']:.3f}",
            f"{c['p90_ms']:.3f}",
            f"{c['p99_ms']:.3f}",
            f"{c['rps']:,.0f}",
            str(c["requests"]),
        ]
        for c in latency["cases"]
    ]
    ratios = [
        f"- {name}: session step p50 / plain act p50 = **{ratio:.2f}×** (target <= "
        f"{LATENCY_TARGET}: {'met' if ratio <= LATENCY_TARGET else 'missed'})"
        for name, ratio in latency["ratios"].items()
    ]
    lines = [
        f"Command: `{latency['command']}`.",
        "",
        latency["setup"],
        "",
        table(["case", "p50 ms", "p90 ms", "p99 ms", "requests/s", "requests"], rows),
        "",
        *ratios,
    ]
    if latency.get("in_process"):
        parts = [[name, f"{ms:.3f}"] for name, ms in latency["in_process"].items()]
        lines += [
            "",
            "Where the time goes, in-process on the same store and episode "
            "(`benchmarks/session_breakdown.py`, median of 1000 calls, no transport):",
            "",
            table(["part", "median ms"], parts),
        ]
    return "\n".join(lines)


def networks_table(results: dict[str, Any]) -> str:
    rows = [
        [
            n["population"],
            str(n["networks"]),
            ", ".join(map(str, n["seeds"])) or "-",
            ", ".join(f"{k} {v}" for k, v in n["gate"].items() if v),
        ]
        for n in results["networks"]
    ]
    return table(["population", "networks", "training seeds", "quality gate"], rows)
