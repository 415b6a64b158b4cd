"""Markdown tables of the report, built from the results (never typed by hand).

| function            | rows                                                              |
|---------------------|-------------------------------------------------------------------|
| `summary_table`     | one per method: returns ± SE, success rates, length               |
| `tests_table`       | one row per comparison and measure: paired mean difference ± SE,  |
|                     | 95 % t interval, rank-biserial r, p and Holm-adjusted p           |
| `unit_rows_table`   | a pair class: per method mean ± SE over pairs, stuck episodes,    |
|                     | regret vs SL, share of pairs with team return at least SL's       |
| `unit_tests_table`  | a class's family of tests over pairs (Wilcoxon; interval, r, Holm)|
| `worst_units_table` | the pairs where a method strands the ego most often               |
| `replicate_table`   | success and stuck episodes per replicate (seed)                   |
| `targets_table`     | the targets of `evaluation.targets` and their numbers             |
| `scaling_table`     | networks each method needs for N = 2..5                           |
| `training_table`    | what one network of each kind cost to train                       |
| `models_table`      | every network the evaluation used: alias, name, version, sha256   |
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from evaluation.backend import ModelRecord
from evaluation.config import METHOD_LABELS
from evaluation.paper.pairs import ReplicateRow, UnitGroup, UnitTest
from evaluation.paper.scaling import KindTraining, networks_needed
from evaluation.stats import MeanSE, MethodSummary, PairedTest, fmt_p


def table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def fmt_ms(value: MeanSE, digits: int = 2) -> str:
    return f"{value.mean:.{digits}f} ± {value.se:.{digits}f}"


def label(method: str) -> str:
    return METHOD_LABELS.get(method, method)


def summary_table(summaries: Sequence[MethodSummary]) -> str:
    rows = [
        (
            label(s.method),
            fmt_ms(s.ego),
            fmt_ms(s.others),
            fmt_ms(s.team),
            f"{s.ego_success:.2f}",
            f"{s.ego_reached:.2f}",
            f"{s.partner_success:.2f}",
            f"{s.solved:.2f}",
            fmt_ms(s.length, 1),
        )
        for s in summaries
    ]
    header = (
        "method",
        "ego return",
        "partners' return",
        "team return",
        "ego success",
        "ego reached",
        "partner success",
        "solved",
        "length",
    )
    return table(header, rows)


TEST_NAMES = {"wilcoxon": "Wilcoxon", "mcnemar": "McNemar"}
TESTS_HEADER = (
    "paired difference",
    "measure",
    "test",
    "n",
    "mean ± SE",
    "95 % CI (t)",
    "r (rank-biserial)",
    "p",
    "p (Holm)",
)


def tests_table(tests: Sequence[PairedTest]) -> str:
    """One row per compared pair and measure, in the order given (Δ = method − other): mean ± SE,
    the 95 % t interval, the rank-biserial effect size, p and its Holm-adjusted value within the
    given tests (their family). Each row is keyed by the whole (method, other, measure), so two
    comparisons that share `other` (AAIL − SL and AAIL-B − SL) keep their own rows."""
    seen: set[tuple[str, str, str]] = set()
    rows = []
    for t in tests:
        key = (t.method, t.other, t.measure)
        if key in seen:
            raise ValueError(
                f"tests_table: {label(t.method)} − {label(t.other)} on {t.measure} twice"
            )
        seen.add(key)
        rows.append(
            [
                f"{label(t.method)} − {label(t.other)}",
                t.measure,
                TEST_NAMES.get(t.test, t.test),
                str(t.n),
                fmt_ms(t.diff),
                str(t.ci),
                f"{t.effect:+.2f}",
                fmt_p(t.p),
                "-" if t.p_holm is None else fmt_p(t.p_holm),
            ]
        )
    return table(TESTS_HEADER, rows)


def unit_rows_table(group: UnitGroup) -> str:
    rows = []
    for m, r in group.rows.items():
        regret = "" if m == "sl" else f"{r.regret_median:.1%} / {r.regret_mean:.1%}"
        within = "" if m == "sl" else f"{r.team_within_share:.0%} / {r.team_above_share:.0%}"
        rows.append(
            [
                label(m),
                str(r.n_units),
                fmt_ms(r.means["ego"]),
                fmt_ms(r.means["others"]),
                fmt_ms(r.means["team"]),
                f"{r.means['ego_success'].mean:.3f}",
                f"{r.stuck_episodes} / {r.episodes:,} ({r.units_with_stuck})",
                regret,
                within,
                fmt_ms(r.means["length"], 1),
            ]
        )
    header = [
        "method",
        "pairs",
        "ego return",
        "others' return",
        "team return",
        "ego success",
        "stuck episodes (pairs)",
        "regret vs SL: median / mean",
        "team ≥ SL − 2 % / > SL",
        "length",
    ]
    return table(header, rows)


UNIT_TESTS_HEADER = (
    "paired difference",
    "measure",
    "pairs",
    "mean ± SE over pairs",
    "95 % CI (t)",
    "r (rank-biserial)",
    "p (Wilcoxon)",
    "p (Holm)",
    "first higher in",
)


def unit_tests_table(family: Sequence[UnitTest]) -> str:
    """One row per test of a class's family (`evaluation.paper.pairs.class_family`)."""
    rows = [
        [
            f"{label(t.method)} − {label(t.other)}",
            t.measure,
            str(t.n_units),
            fmt_ms(t.diff),
            str(t.ci),
            f"{t.effect:+.2f}",
            fmt_p(t.p),
            "-" if t.p_holm is None else fmt_p(t.p_holm),
            f"{t.better:.0%}",
        ]
        for t in family
    ]
    return table(UNIT_TESTS_HEADER, rows)


def worst_units_table(group: UnitGroup, methods: Sequence[str], k: int = 8) -> str:
    rows = []
    for method in methods:
        if method not in group.rows:
            continue
        for u in group.worst(method, k):
            team = u.by_method[method]["team"] - u.by_method["sl"]["team"]
            rows.append(
                [
                    label(method),
                    f"`{u.combo}`",
                    f"{u.stuck_episodes[method]} / {u.episodes}",
                    f"{u.regret(method):.0%}",
                    f"{team:+.2f}",
                ]
            )
    return table(["method", "pair", "stuck episodes", "regret vs SL", "team − SL"], rows)


def replicate_table(rows: Sequence[ReplicateRow], methods: Sequence[str]) -> str:
    body = [
        [
            str(r.replicate),
            str(r.seed),
            r.label,
            label(r.method),
            str(r.units),
            f"{r.ego_success:.3f}",
            str(r.stuck_episodes),
            f"{r.team:.2f}",
        ]
        for r in rows
        if r.method in methods
    ]
    header = [
        "replicate",
        "seed",
        "class",
        "method",
        "pairs",
        "ego success",
        "stuck episodes",
        "team return",
    ]
    return table(header, body)


def targets_table(targets: Sequence[Any]) -> str:
    """One row per target of `evaluation.targets` (its checks and their numbers)."""
    rows = [
        [
            t.key,
            label(t.method),
            t.title,
            "<br>".join(f"{'✔' if c.passed else '✘'} {c.text}: {c.detail}" for c in t.checks),
            f"**{t.verdict}**",
        ]
        for t in targets
    ]
    return table(["target", "method", "what", "checks", "verdict"], rows)


def scaling_table(n_goals: int = 35, agents: Sequence[int] = (2, 3, 4, 5)) -> str:
    rows = []
    for n in agents:
        need = networks_needed(n_goals, n)
        rows.append(
            [str(n), f"{need['sl']:,}", f"{need['nail']:,}", f"{need['aail']:,}", f"{need['jl']:,}"]
        )
    return table(["agents N", "SL", "NAIL", "AAIL", "JL"], rows)


def training_table(costs: Sequence[KindTraining]) -> str:
    rows = []
    for c in costs:
        wall = "not measured"
        if c.wall is not None:
            wall = f"{c.wall.per_network_s:.1f} s ({c.wall.networks} networks in {c.wall.wall_s:.0f} s)"
        rows.append(
            [
                c.kind,
                str(c.versions),
                c.hidden,
                f"{c.steps:,.0f}",
                f"{c.transitions:,.0f}",
                f"{c.updates:,.0f}",
                wall,
            ]
        )
    header = [
        "kind",
        "versions in store",
        "hidden",
        "batched steps / network",
        "env transitions / network",
        "updates / network",
        "wall time / network",
    ]
    return table(header, rows)


def models_table(
    models: Iterable[tuple[str, ModelRecord]], gates: Mapping[tuple[str, int], str]
) -> str:
    """Every network used; `gates` (from the store's lineage) may be empty (server runs)."""
    rows = [
        [
            alias,
            m.role,
            f"`{m.name}`",
            str(m.version),
            gates.get((m.name, m.version), "?"),
            f"`{m.sha256}`",
        ]
        for alias, m in sorted(models, key=lambda am: (am[0], am[1].role, am[1].name))
    ]
    return table(["requested alias", "role", "name", "version", "gate", "sha256"], rows)
