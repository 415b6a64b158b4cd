"""The committed partners reports say what their data says: each REPORT.md's verdicts and tables
are what `evaluation.partners.report` computes from the rows of its results.json, and ZOOS.md is
the spread of those runs."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from evaluation.partners.report import Row, tables_markdown
from evaluation.partners.spread import spread_markdown

REPORTS = Path(__file__).resolve().parents[3] / "reports" / "partners"
PREVIOUS = REPORTS / "previous_rule"  # AAIL-B's earlier rule, three zoos
RUNS = {
    "zoo seed 0": PREVIOUS,
    "zoo seed 10": PREVIOUS / "zoo10",
    "zoo seed 20": PREVIOUS / "zoo20",
}
CURRENT = {  # AAIL-B's current rule, the same three zoos' seeds
    "zoo seed 0": REPORTS,
    "zoo seed 10": REPORTS / "zoo10",
    "zoo seed 20": REPORTS / "zoo20",
}
# A fresh draw on three zoos retrained on another machine (seeds 0, 10, 20): per zoo, AAIL-B
# with the environment's answers, without them (no_oracle) and with goal monitors instead
DRAW = REPORTS / "draw6262"
DRAWS = {"zoo seed 0": DRAW, "zoo seed 10": DRAW / "zoo10", "zoo seed 20": DRAW / "zoo20"}
FLAGS = {"no_oracle": ["--no-goal-oracle", "--no-goal-monitor"], "monitor": ["--no-goal-oracle"]}
# Another fresh draw on three zoos retrained again, with the monitors that learn the target less
# its edge strip: per zoo, AAIL-B with the environment's answers and with the monitors instead
DRAW_8383 = REPORTS / "draw8383"
DRAWS_8383 = {
    "zoo seed 0": DRAW_8383,
    "zoo seed 10": DRAW_8383 / "zoo10",
    "zoo seed 20": DRAW_8383 / "zoo20",
}
WAYS = [(DRAWS, "no_oracle"), (DRAWS, "monitor"), (DRAWS_8383, "monitor")]
REPORTED = {
    **{f"current rule, {k}": v for k, v in CURRENT.items()},
    **{f"earlier rule, {k}": v for k, v in RUNS.items()},
    **{f"draw 6262, {k}": v for k, v in DRAWS.items()},
    **{f"draw 6262, {k}, {way}": v / way for k, v in DRAWS.items() for way in FLAGS},
    **{f"draw 8383, {k}": v for k, v in DRAWS_8383.items()},
    **{f"draw 8383, {k}, monitor": v / "monitor" for k, v in DRAWS_8383.items()},
}
DEFAULT = "aail_bounded"  # the server's default blend, as each report names it


def _rows(run: Path) -> tuple[list[Row], tuple[str, ...]]:
    data = json.loads((run / "results.json").read_text())
    rows: list[Row] = []
    for r in data["rows"]:
        fields: dict[str, Any] = {k: (math.nan if v is None else v) for k, v in r.items()}
        rows.append(Row(**fields))
    return rows, tuple(data["config"]["methods"])


@pytest.mark.parametrize("label", sorted(REPORTED))
def test_each_report_holds_the_tables_its_results_give(label: str) -> None:
    run = REPORTED[label]
    rows, methods = _rows(run)
    report = (run / "REPORT.md").read_text()
    assert "## Verdicts for AAIL-B (the server's default)" in report
    assert report.endswith(tables_markdown(rows, DEFAULT, methods))


@pytest.mark.parametrize(
    ("zoos", "page"),
    [
        (CURRENT, REPORTS / "ZOOS.md"),
        (RUNS, PREVIOUS / "ZOOS.md"),
        (DRAWS, DRAW / "ZOOS.md"),
        ({k: v / "monitor" for k, v in DRAWS.items()}, DRAW / "MONITORS.md"),
        (DRAWS_8383, DRAW_8383 / "ZOOS.md"),
        ({k: v / "monitor" for k, v in DRAWS_8383.items()}, DRAW_8383 / "MONITORS.md"),
    ],
)
def test_each_spread_page_is_the_spread_of_its_three_runs(
    zoos: dict[str, Path], page: Path
) -> None:
    runs = [json.loads((run / "results.json").read_text()) for run in zoos.values()]
    table = spread_markdown(runs, list(zoos))
    assert table in page.read_text()


@pytest.mark.parametrize(("draws", "way"), WAYS)
@pytest.mark.parametrize("zoo", sorted(DRAWS))
def test_the_runs_without_the_oracle_differ_only_in_aail_b(
    draws: dict[str, Path], way: str, zoo: str
) -> None:
    """The runs without the oracle are the same draw, episodes and engine but for AAIL-B's
    R2-R4: every other method's row is the oracle run's, and each report says how AAIL-B ran."""
    run, flags = draws[zoo] / way, FLAGS[way]
    with_oracle = json.loads((draws[zoo] / "results.json").read_text())
    without = json.loads((run / "results.json").read_text())
    assert with_oracle["config"] == without["config"]
    for a, b in zip(with_oracle["rows"], without["rows"], strict=True):
        assert (a["partner_type"], a["method"]) == (b["partner_type"], b["method"])
        if a["method"] != DEFAULT:  # Holm's adjustment runs over a family AAIL-B is in
            assert _unadjusted(a) == _unadjusted(b)
    report = (run / "REPORT.md").read_text()
    command = next(line for line in report.splitlines() if line.startswith("- Command:"))
    assert all(flag in command for flag in flags) and "without the goal oracle" in report
    assert ("--no-goal-monitor" in command) == ("without goal monitors" in report)


def _unadjusted(row: dict[str, Any]) -> str:
    """The row without its Holm-adjusted p-values, as JSON (NaN equal to NaN)."""
    return json.dumps({k: v for k, v in row.items() if "holm" not in k})
