"""The partners suite's verdicts and report: what each method costs the ego and brings the team,
per partner type and class, against SL on the same episodes.

Units are goal pairs (or five-agent sets): each is reduced to its per-method means over its
episodes, and tests run over units (`evaluation.paper.pairs`), not over episodes of one pair.

| measure          | per partner type, class and method                                      |
|------------------|-------------------------------------------------------------------------|
| `stranded`       | episodes where SL's ego ends inside its target and the method's does not |
|                  | (paired by start and random numbers): the failure a user meets          |
| `regret_median`  | median over units of (SL ego − method ego) / |SL ego|                    |
| `team_gain`      | mean over units of method team − SL team, its 95 % t interval, Wilcoxon |
|                  | p (two-sided; Holm-adjusted over the methods of one partner type and    |
|                  | class, the family); the paired TOST p within ±2 % of |SL team| (equivalent), |
|                  | and its lower one-sided p (not below SL by more than 2 %: the verdict)  |
| `help_kept`      | aligned pairs: method's team gain over SL's / the paper AAIL's gain     |
| `sets_below`     | five agents: sets whose team return is below SL's                       |

The bars (`BARS`) are the product's promise for its default blend: never strand the ego where
SL would not; on non-aligned pairs a median regret of at most 5 % and a team return equivalent
to or above SL's; on aligned pairs with room to help at least the paper AAIL's gain, above SL
with p < 0.01; with five agents no set below SL. "Not below SL" is judged by the non-inferiority
half of the paired TOST (H0: the mean gain is at most −2 % of |SL's team return|), not by a
large p of a difference test; the full TOST p says whether the two are equivalent.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.config import METHOD_LABELS
from evaluation.partners.suite import PartnersResult
from evaluation.rollout import CellResult
from evaluation.stats import holm, paired_ci, tost_paired, wilcoxon_p

BLENDS = ("aail_bounded", "aail_budget")  # the blends judged by the bars, in this order
TOST_MARGIN = 0.02  # equivalence margin for "not below SL": ±2 % of |SL's mean team return|
REGRET_BAR = 0.05  # median own-return regret on non-aligned pairs
HELP_P = 0.01  # aligned pairs with room to help: above SL at this level


@dataclass(frozen=True)
class Row:
    """One method against SL in one (partner type, class) block."""

    partner_type: str
    kind: str
    method: str
    units: int
    episodes: int
    stranded: int
    regret_median: float
    team: float
    team_gain: float
    gain_low: float  # 95 % t interval of the mean gain over units
    gain_high: float
    gain_p: float  # Wilcoxon, two-sided, over units
    gain_p_holm: float  # Holm-adjusted within its family: one block's methods against SL
    tost_p: float  # paired TOST within ±TOST_MARGIN |SL team| (max of the two one-sided p's)
    not_below_p: float  # its lower one-sided test: H0 mean gain <= -TOST_MARGIN |SL team|
    help_kept: float  # gain / the paper AAIL's gain (aligned); NaN elsewhere
    sets_below: int  # units whose team return is below SL's


def _by_unit(cells: list[CellResult], method: str) -> dict[str, CellResult]:
    return {c.scenario.name: c for c in cells if c.method == method}


def rows_of(result: PartnersResult) -> list[Row]:
    rows = []
    for ptype, by_class in result.cells.items():
        for kind, cells in by_class.items():
            sl = _by_unit(cells, "sl")
            aail = _by_unit(cells, "aail")
            units = sorted(sl)
            if not units:
                continue
            sl_team = np.array([sl[u].team_E.mean() for u in units])
            sl_ego = np.array([sl[u].returns_EN[:, 0].mean() for u in units])
            aail_gain = np.array([aail[u].team_E.mean() for u in units]) - sl_team if aail else None
            for method in result.config.methods:
                mine = _by_unit(cells, method)
                team = np.array([mine[u].team_E.mean() for u in units])
                ego = np.array([mine[u].returns_EN[:, 0].mean() for u in units])
                gain = team - sl_team
                interval = paired_ci(team, sl_team)
                tost = tost_paired(team, sl_team, margin_fraction=TOST_MARGIN)
                stranded = sum(
                    int((sl[u].success_EN[:, 0] & ~mine[u].success_EN[:, 0]).sum()) for u in units
                )
                kept = float("nan")
                if kind == "aligned" and aail_gain is not None and aail_gain.mean() != 0:
                    kept = float(gain.mean() / aail_gain.mean())
                rows.append(
                    Row(
                        partner_type=ptype,
                        kind=kind,
                        method=method,
                        units=len(units),
                        episodes=int(sum(mine[u].length_E.size for u in units)),
                        stranded=stranded,
                        regret_median=float(np.median((sl_ego - ego) / np.abs(sl_ego))),
                        team=float(team.mean()),
                        team_gain=float(gain.mean()),
                        gain_low=interval.low,
                        gain_high=interval.high,
                        gain_p=wilcoxon_p(team, sl_team),
                        gain_p_holm=float("nan"),  # set below, once the family is known
                        tost_p=max(tost.p_lower, tost.p_upper),
                        not_below_p=tost.p_lower,
                        help_kept=kept,
                        sets_below=int((team < sl_team).sum()),
                    )
                )
    return _holm_by_block(rows)


def _holm_by_block(rows: list[Row]) -> list[Row]:
    """Each (partner type, class) block's Wilcoxon p's against SL (SL itself left out) as one
    family, Holm-adjusted."""
    out = list(rows)
    blocks: dict[tuple[str, str], list[int]] = {}
    for i, r in enumerate(rows):
        if r.method != "sl":
            blocks.setdefault((r.partner_type, r.kind), []).append(i)
    for members in blocks.values():
        adjusted = holm([rows[i].gain_p for i in members])
        for i, p in zip(members, adjusted, strict=True):
            out[i] = replace(rows[i], gain_p_holm=p)
    return out


@dataclass(frozen=True)
class Verdict:
    partner_type: str
    bar: str
    met: bool
    detail: str


def verdicts(rows: list[Row], method: str) -> list[Verdict]:
    """The bars of the module docstring for `method`, per partner type."""
    out = []
    for ptype in dict.fromkeys(r.partner_type for r in rows):
        mine = {r.kind: r for r in rows if r.partner_type == ptype and r.method == method}
        aail = {r.kind: r for r in rows if r.partner_type == ptype and r.method == "aail"}
        stranded = sum(r.stranded for r in mine.values())
        episodes = sum(r.episodes for r in mine.values())
        out.append(
            Verdict(ptype, "never strands", stranded == 0, f"{stranded} of {episodes} episodes")
        )
        if "non_aligned" in mine:
            r = mine["non_aligned"]
            ok = r.regret_median <= REGRET_BAR and r.not_below_p < 0.05
            out.append(
                Verdict(
                    ptype,
                    "non-aligned: regret ≤ 5 %, team not below SL (−2 % margin)",
                    ok,
                    f"regret median {100 * r.regret_median:.1f} %, team − SL "
                    f"{r.team_gain:+.3f} [{r.gain_low:+.3f}, {r.gain_high:+.3f}], "
                    f"non-inferiority p = {r.not_below_p:.2g} (TOST p = {r.tost_p:.2g})",
                )
            )
        if "aligned" in mine and "aligned" in aail:
            r, a = mine["aligned"], aail["aligned"]
            ok = r.team_gain >= a.team_gain and r.team_gain > 0 and r.gain_p_holm < HELP_P
            out.append(
                Verdict(
                    ptype,
                    "aligned: gain ≥ AAIL's, > SL (p < 0.01)",
                    ok,
                    f"gain {r.team_gain:+.3f} vs AAIL {a.team_gain:+.3f} "
                    f"({100 * r.help_kept:.0f} % kept), Holm p = {r.gain_p_holm:.2g}",
                )
            )
        if "five_agents" in mine:
            r = mine["five_agents"]
            out.append(
                Verdict(
                    ptype,
                    "five agents: no set below SL",
                    r.sets_below == 0,
                    f"{r.sets_below} of {r.units} sets below SL, team − SL {r.team_gain:+.3f}",
                )
            )
    return out


KIND_LABELS = {
    "aligned": "aligned, room to help",
    "non_aligned": "non-aligned",
    "five_agents": "five agents",
}


def _fmt(x: float, spec: str = "+.3f") -> str:
    return "–" if isinstance(x, float) and math.isnan(x) else format(x, spec)


def to_markdown(
    result: PartnersResult, rows: list[Row], default: str, command: str, backend: str
) -> str:
    c = result.config
    lines = [
        "# Every method against partners that are not coexist's own networks",
        "",
        "Generated by `coexist eval --suite partners` from the episodes of the command below; "
        "every number and verdict is computed (`evaluation/partners/`).",
        "",
        f"- Command: `{command}`",
        f"- Backend: {backend}; {result.backend_calls:,} policy calls.",
        f"- Seed {c.seed}: {c.aligned_pairs} aligned pairs with room to help and "
        f"{c.non_aligned_pairs} non-aligned pairs × {c.pair_episodes} episodes, "
        f"{c.five_agent_sets} five-agent sets × {c.set_episodes} episodes, per partner type; "
        f"at most {c.max_steps} steps. Partner types: `evaluation/partner_types.py`.",
        f"- Units are pairs (or sets): tests over their per-method means. Team gain: mean of "
        f"method − SL over units, 95 % t interval, Wilcoxon p; TOST: paired equivalence "
        f"within ±{100 * TOST_MARGIN:.0f} % of |SL's team return| (p < 0.05: equivalent); "
        f"not below: its lower one-sided test (p < 0.05: not more than "
        f"{100 * TOST_MARGIN:.0f} % below SL).",
        "- What the numbers say, in words: [discussion.md](discussion.md) (hand-written).",
        "",
    ]
    return "\n".join(lines) + "\n" + tables_markdown(rows, default, c.methods)


def tables_markdown(rows: list[Row], default: str, methods: tuple[str, ...]) -> str:
    """The verdicts and the three tables of a report: everything below its header, computed
    from `rows` alone (so a test can check a committed report against its results.json)."""
    lines: list[str] = []
    judged = [default] + [m for m in BLENDS if m != default and m in methods]
    for method in judged:
        role = "the server's default" if method == default else "an option"
        lines += [
            f"## Verdicts for {METHOD_LABELS.get(method, method)} ({role})",
            "",
            "| partner type | bar | met | measured |",
            "|---|---|---|---|",
        ]
        for v in verdicts(rows, method):
            lines.append(f"| {v.partner_type} | {v.bar} | {'✔' if v.met else '✘'} | {v.detail} |")
        lines.append("")
    for kind in ("aligned", "non_aligned", "five_agents"):
        block = [r for r in rows if r.kind == kind]
        if not block:
            continue
        lines += [
            "",
            f"## {KIND_LABELS[kind]}",
            "",
            "| partner type | method | units | stranded | regret median | team | team − SL "
            "[95 % CI] | Wilcoxon p (Holm) | TOST p | not below p | help kept | units below SL |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in block:
            lines.append(
                f"| {r.partner_type} | {METHOD_LABELS.get(r.method, r.method)} | {r.units} | "
                f"{r.stranded} | {100 * r.regret_median:.1f} % | {r.team:.2f} | "
                f"{_fmt(r.team_gain)} [{_fmt(r.gain_low)}, {_fmt(r.gain_high)}] | "
                f"{r.gain_p:.2g} ({_fmt(r.gain_p_holm, '.2g')}) | {r.tost_p:.2g} | "
                f"{r.not_below_p:.2g} | "
                f"{_fmt(100 * r.help_kept, '.0f')}{'' if math.isnan(r.help_kept) else ' %'} | "
                f"{r.sets_below} |"
            )
    return "\n".join(lines) + "\n"


def results_json(result: PartnersResult, rows: list[Row]) -> dict[str, Any]:
    return {
        "config": asdict(result.config),
        "rows": [asdict(r) for r in rows],
        "units": {
            ptype: {
                kind: sorted({c.scenario.combo for c in cells}) for kind, cells in by_kind.items()
            }
            for ptype, by_kind in result.cells.items()
        },
    }


def write_report(
    result: PartnersResult, out: Path, *, default: str, command: str, backend: str
) -> Path:
    """REPORT.md and results.json into `out`; the report's path."""
    rows = rows_of(result)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(
        json.dumps(results_json(result, rows), indent=1, allow_nan=True) + "\n"
    )
    report = out / "REPORT.md"
    report.write_text(to_markdown(result, rows, default, command, backend))
    return report
