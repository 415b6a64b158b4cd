"""The report's tables checked against the episodes they come from.

`check_report_against_results` reads a generated REPORT.md and its results.json, recomputes every
row of the scenario tables and of the pair-class tables of tests from the episodes alone (scipy
for the tests and intervals, the rank-biserial and Holm's adjustment written out here), and
compares them with the printed numbers. A row that shows another comparison's numbers, a label
that names the wrong methods, a missing or extra comparison, or a wrong adjustment fails it.
`tests/evaluation/paper/test_eval_suite.py` runs it on the `--fast` suite's real report.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats as sps

from evaluation.config import METHOD_LABELS, Scenario, SuiteConfig
from evaluation.paper import report
from evaluation.paper.pairs import CLASS_COMPARISONS, GROUP_LABELS, pair_groups
from evaluation.paper.suite import SuiteResult, results_json
from evaluation.rollout import CellResult

LABEL_METHOD = {v: k for k, v in METHOD_LABELS.items()}
PAPER_SCENARIOS = {
    "aligned": "## Goal-aligned scenario",
    "non_aligned": "## Non-aligned scenario",
    "five_agents": "## Five agents",
}
# What the scenario tables must compare, whenever both methods ran
SCENARIO_PAIRS = [
    ("aail", "sl"),
    ("aail", "nail"),
    ("aail", "aail_bounded"),
    ("aail", "aail_budget"),
    ("aail", "jl"),
    ("aail_bounded", "sl"),
    ("aail_budget", "sl"),
    ("nail", "sl"),
]


# -- reading the report ----------------------------------------------------------------------


def section(text: str, heading: str) -> str:
    """The text from `heading` (a line starting with it) to the next heading of its level."""
    level = heading.split(" ")[0]
    start = next(i for i, line in enumerate(text.splitlines()) if line.startswith(heading))
    lines = text.splitlines()[start + 1 :]
    end = next((i for i, line in enumerate(lines) if re.match(rf"^{level} ", line)), len(lines))
    return "\n".join(lines[:end])


def tables_in(text: str) -> list[list[list[str]]]:
    """Every markdown table: rows of stripped cells, the header first, the rule dropped."""
    tables: list[list[list[str]]] = []
    current: list[list[str]] = []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if not all(set(c) <= {"-"} for c in cells):
                current.append(cells)
        elif current:
            tables.append(current)
            current = []
    return tables


def table_with(text: str, first_columns: tuple[str, ...]) -> list[dict[str, str]]:
    """The one table whose header starts with `first_columns`, as dicts by header."""
    found = [t for t in tables_in(text) if tuple(t[0][: len(first_columns)]) == first_columns]
    assert len(found) == 1, f"expected one table starting {first_columns}, found {len(found)}"
    header, *rows = found[0]
    return [dict(zip(header, row, strict=True)) for row in rows]


def mean_se_of(cell: str) -> tuple[float, float]:
    mean, se = cell.split(" ± ")
    return float(mean), float(se)


def interval_of(cell: str) -> tuple[float, float]:
    low, high = cell.strip("[]").split(", ")
    return float(low), float(high)


# results.json keeps returns to 4 decimals: a sum or mean of them may move by a few 1e-4
JSON_ROUNDING = 1e-3


def close(printed: float, value: float, digits: int = 2) -> bool:
    """`printed` is `value` rounded to `digits` decimals (infinite values print as inf)."""
    if not np.isfinite(value):
        return printed == value
    return abs(printed - value) <= 0.5 * 10**-digits + JSON_ROUNDING


def same_p(printed: str, value: float) -> bool:
    """A p printed with two significant digits is `value`."""
    return bool(np.isclose(float(printed), value, rtol=0.051, atol=0.0))


# -- the numbers from the episodes -----------------------------------------------------------


def cells_from_json(data: Mapping[str, Any]) -> dict[str, dict[str, CellResult]]:
    """results.json's episodes back as cell results: scenario name -> method -> cell."""
    out: dict[str, dict[str, CellResult]] = {}
    for key, c in data["cells"].items():
        name, method = key.rsplit("/", 1)
        returns = np.array(c["returns"], dtype=float)
        goals = c["goals"]
        scenario = Scenario(
            name, goals[0], tuple(goals[1:]), len(returns), c["start_seed"], c["replicate"]
        )
        out.setdefault(name, {})[method] = CellResult(
            scenario=scenario,
            method=method,
            returns_EN=returns,
            success_EN=np.array(c["success"], dtype=bool),
            reached_EN=np.array(c["reached"], dtype=bool),
            length_E=np.array(c["length"]),
            solved_E=np.array(c["solved"], dtype=bool),
            trajectory_TN4=np.zeros((1, returns.shape[1], 4)),
        )
    return out


def episode_measure(c: CellResult, measure: str) -> np.ndarray:
    return {
        "ego return": lambda: c.returns_EN[:, 0],
        "others' return": lambda: c.returns_EN[:, 1:].sum(axis=1),
        "team return": lambda: c.returns_EN.sum(axis=1),
        "length": lambda: c.length_E.astype(float),
        "ego success": lambda: c.success_EN[:, 0].astype(float),
    }[measure]()


def rank_biserial_here(d: np.ndarray) -> float:
    d = d[d != 0]
    if d.size == 0:
        return 0.0
    ranks = sps.rankdata(np.abs(d))
    return float((ranks[d > 0].sum() - ranks[d < 0].sum()) / ranks.sum())


def holm_here(ps: list[float]) -> list[float]:
    m, order = len(ps), sorted(range(len(ps)), key=lambda i: ps[i])
    out, running = [0.0] * m, 0.0
    for k, i in enumerate(order):
        running = max(running, min(1.0, (m - k) * ps[i]))
        out[i] = running
    return out


def expected_row(a: np.ndarray, b: np.ndarray, test: str) -> dict[str, float]:
    d = a - b
    n = d.size
    se = float(d.std(ddof=1) / np.sqrt(n)) if n > 1 else 0.0
    if n < 2:
        low, high = -np.inf, np.inf
    elif se == 0.0:
        low = high = float(d.mean())
    else:
        ci = sps.ttest_1samp(d, 0.0).confidence_interval(0.95)
        low, high = float(ci.low), float(ci.high)
    if test == "McNemar":
        only_a, only_b = int(np.sum(d > 0)), int(np.sum(d < 0))
        p = 1.0 if only_a + only_b == 0 else sps.binomtest(only_a, only_a + only_b).pvalue
    else:
        p = 1.0 if not np.any(d != 0) else sps.wilcoxon(d).pvalue
        p = p if np.isfinite(p) else 1.0
    return {
        "mean": float(d.mean()),
        "se": se,
        "low": low,
        "high": high,
        "r": rank_biserial_here(d),
        "p": float(p),
    }


def check_test_rows(rows: list[dict[str, str]], expected: list[dict[str, float]]) -> None:
    """Printed rows against expected numbers, the Holm adjustment over the table's rows."""
    holm = holm_here([e["p"] for e in expected])
    for row, want, p_holm in zip(rows, expected, holm, strict=True):
        where = f"{row['paired difference']} / {row['measure']}"
        mean_col = "mean ± SE" if "mean ± SE" in row else "mean ± SE over pairs"
        mean, se = mean_se_of(row[mean_col])
        assert close(mean, want["mean"]) and close(se, want["se"]), (where, row, want)
        low, high = interval_of(row["95 % CI (t)"])
        assert close(low, want["low"]) and close(high, want["high"]), (where, row, want)
        assert close(float(row["r (rank-biserial)"]), want["r"]), (where, row, want)
        p_col = "p" if "p" in row else "p (Wilcoxon)"
        assert same_p(row[p_col], want["p"]), (where, row, want)
        assert same_p(row["p (Holm)"], p_holm), (where, row, p_holm)


def check_scenario_section(text: str, cells: Mapping[str, CellResult]) -> None:
    summary = table_with(text, ("method", "ego return"))
    assert [r["method"] for r in summary] == [METHOD_LABELS[m] for m in cells]
    for r in summary:
        c = cells[LABEL_METHOD[r["method"]]]
        for column, measure in (("ego return", "ego return"), ("team return", "team return")):
            values = episode_measure(c, measure)
            mean, se = mean_se_of(r[column])
            want_se = values.std(ddof=1) / np.sqrt(values.size) if values.size > 1 else 0.0
            assert close(mean, values.mean()) and close(se, want_se), (r, column)
        assert close(float(r["ego success"]), c.success_EN[:, 0].mean())
    rows = table_with(text, ("paired difference", "measure", "test"))
    pairs = [(m, o) for m, o in SCENARIO_PAIRS if m in cells and o in cells]
    labels = list(dict.fromkeys(r["paired difference"] for r in rows))
    assert labels == [f"{METHOD_LABELS[m]} − {METHOD_LABELS[o]}" for m, o in pairs]
    expected = []
    for r in rows:
        method, other = (LABEL_METHOD[x] for x in r["paired difference"].split(" − "))
        assert r["n"] == str(cells[method].returns_EN.shape[0])
        a = episode_measure(cells[method], r["measure"])
        b = episode_measure(cells[other], r["measure"])
        want_test = "McNemar" if r["measure"] == "ego success" else "Wilcoxon"
        assert r["test"] == want_test, r
        expected.append(expected_row(a, b, want_test))
    check_test_rows(rows, expected)


def check_class_section(text: str, group_units: list[Any]) -> None:
    rows = table_with(text, ("paired difference", "measure", "pairs"))
    by_method = [u.by_method for u in group_units]
    ran = {m for b in by_method for m in b}
    pairs = [(m, o) for m, o in CLASS_COMPARISONS if m in ran and o in ran]
    labels = list(dict.fromkeys(r["paired difference"] for r in rows))
    assert labels == [f"{METHOD_LABELS[m]} − {METHOD_LABELS[o]}" for m, o in pairs]
    expected = []
    for r in rows:
        method, other = (LABEL_METHOD[x] for x in r["paired difference"].split(" − "))
        both = [b for b in by_method if method in b and other in b]
        assert r["pairs"] == str(len(both))
        a = np.array([b[method][r["measure"]] for b in both])
        b_ = np.array([b[other][r["measure"]] for b in both])
        expected.append(expected_row(a, b_, "Wilcoxon"))
    check_test_rows(rows, expected)


def check_report_against_results(report_text: str, data: Mapping[str, Any]) -> int:
    """Every scenario table and every pair-class table of tests against results.json; returns
    how many tables were checked."""
    cells = cells_from_json(data)
    checked = 0
    for name, heading in PAPER_SCENARIOS.items():
        check_scenario_section(section(report_text, heading), cells[name])
        checked += 2
    pair_cells = [
        c for name, by in cells.items() if name not in PAPER_SCENARIOS for c in by.values()
    ]
    headings = {
        "aligned": "### Aligned pairs (",
        "room_to_help": "### Aligned pairs with room to help (",
        "non_aligned": "### Non-aligned pairs (",
        "mixed": "### Mixed pairs (",
        "five_agents": "### Five agents, random goal sets (",
    }
    for key, group in pair_groups(pair_cells).items():
        assert key in GROUP_LABELS
        check_class_section(section(report_text, headings[key]), list(group.units))
        checked += 1
    return checked


# -- a report generated from known episodes --------------------------------------------------


def synthetic_cell(scenario: Scenario, method: str, rng: np.random.Generator) -> CellResult:
    n, agents = scenario.episodes, scenario.n_agents
    shift = {
        "sl": 0.0,
        "nail": 2.0,
        "aail": 1.0,
        "aail_bounded": 0.5,
        "aail_budget": 0.8,
        "jl": -0.5,
    }[method]
    returns = -10.0 + rng.normal(0.0, 1.0, (n, agents))
    returns[:, 1:] += shift
    returns[:, 0] -= shift / 4
    returns = returns.round(4)  # as results.json keeps them
    success = np.ones((n, agents), dtype=bool)
    success[:, 0] = rng.random(n) > (0.6 if method == "nail" else 0.1)
    return CellResult(
        scenario=scenario,
        method=method,
        returns_EN=returns,
        success_EN=success,
        reached_EN=success.copy(),
        length_E=rng.integers(10, 50, n),
        solved_E=np.asarray(success.all(axis=1)),
        trajectory_TN4=np.zeros((1, agents, 4)),
    )


def synthetic_result() -> SuiteResult:
    rng = np.random.default_rng(11)
    config = SuiteConfig(replicates=1)
    methods = ("sl", "nail", "aail", "aail_bounded", "aail_budget", "jl")
    paper = [
        Scenario("aligned", "c", ("c4",), 30, 1),
        Scenario("non_aligned", "a2", ("b3",), 30, 2),
        Scenario("five_agents", "a2", ("a0", "b2", "c4", "e1"), 20, 3),
    ]
    cells = {s.name: {m: synthetic_cell(s, m, rng) for m in methods} for s in paper}
    pairs = [("c", "c4"), ("b", "d0"), ("2", "c2"), ("a2", "b3"), ("a0", "e4"), ("b0", "e2")]
    pair_results = [
        synthetic_cell(Scenario(f"pair:{e}+{p}", e, (p,), 6, 100 + k), m, rng)
        for k, (e, p) in enumerate(pairs)
        for m in (methods if k % 2 else methods[:-1])  # JL on some pairs only
    ]
    jl = {s.name: True for s in paper} | {r.scenario.name: True for r in pair_results}
    return SuiteResult(config, "synthetic", paper, cells, pair_results, jl)


def test_generated_tables_match_their_episodes() -> None:
    result = synthetic_result()
    text = "\n\n".join(
        [
            PAPER_SCENARIOS["aligned"],
            report._scenario_section(result, "aligned", "fig.png"),
            PAPER_SCENARIOS["non_aligned"],
            report._scenario_section(result, "non_aligned", "fig.png"),
            PAPER_SCENARIOS["five_agents"],
            report._scenario_section(result, "five_agents", "fig.png"),
            "## Goal pairs nobody tuned on",
            report._pairs_section(result, None),
        ]
    )
    data = json.loads(json.dumps(results_json(result)))  # as written and read back
    # 3 scenarios × (summary + tests), and the aligned, room-to-help and non-aligned classes
    assert check_report_against_results(text, data) == 9


def test_the_check_catches_a_row_with_another_comparisons_numbers() -> None:
    """The table bug as it was: the AAIL − SL row showing AAIL-B − SL's numbers."""
    result = synthetic_result()
    text = PAPER_SCENARIOS["aligned"] + "\n" + report._scenario_section(result, "aligned", "f")
    lines = text.splitlines()
    aail = next(i for i, s in enumerate(lines) if s.startswith("| AAIL − SL | team return"))
    bounded = next(i for i, s in enumerate(lines) if s.startswith("| AAIL-B − SL | team return"))
    lines[aail] = lines[bounded].replace("AAIL-B − SL", "AAIL − SL")
    cells = cells_from_json(json.loads(json.dumps(results_json(result))))
    with pytest.raises(AssertionError):
        check_scenario_section(section("\n".join(lines), "## Goal-aligned"), cells["aligned"])
    check_scenario_section(section(text, "## Goal-aligned"), cells["aligned"])


def test_report_files_checked(tmp_path: Path) -> None:
    """The checker reads what `write_report`'s parts write: results.json round-trips."""
    result = synthetic_result()
    path = tmp_path / "results.json"
    path.write_text(json.dumps(results_json(result)))
    cells = cells_from_json(json.loads(path.read_text()))
    original = result.cells["non_aligned"]["aail"]
    back = cells["non_aligned"]["aail"]
    np.testing.assert_allclose(back.returns_EN, original.returns_EN.round(4))
    np.testing.assert_array_equal(back.success_EN, original.success_EN)


REPORTS = Path(__file__).resolve().parents[3] / "reports"
JL_ZOOS = {"zoo seed 0": "joint_learner", "zoo seed 10": "joint_learner/zoo10"}
JL_ZOOS["zoo seed 20"] = "joint_learner/zoo20"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("folder", "tables"), [("paper", 10), *((folder, 3) for folder in JL_ZOOS.values())]
)
def test_the_committed_report_matches_its_committed_results(folder: str, tables: int) -> None:
    """reports/paper/REPORT.md and the joint learner's reports as shipped: every scenario and
    pair-class table of tests against the results.json it was generated from."""
    root = REPORTS / folder
    data = json.loads((root / "results.json").read_text())
    checked = check_report_against_results((root / "REPORT.md").read_text(), data)
    assert checked >= tables


def test_the_joint_learners_zoos_table_is_the_spread_of_its_three_runs() -> None:
    from evaluation.paper.spread import spread_markdown

    runs = [json.loads((REPORTS / f / "results.json").read_text()) for f in JL_ZOOS.values()]
    table = spread_markdown(runs, list(JL_ZOOS))
    assert table in (REPORTS / "joint_learner" / "ZOOS.md").read_text()


def test_the_spread_refuses_runs_that_differ_by_more_than_their_zoo() -> None:
    from evaluation.paper.spread import spread_markdown

    run = json.loads((REPORTS / "joint_learner" / "results.json").read_text())
    other = {**run, "config": {**run["config"], "episodes": 100}}
    with pytest.raises(ValueError, match=r"config\.episodes"):
        spread_markdown([run, other], ["a", "b"])
