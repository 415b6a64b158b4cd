"""`coexist eval --suite partners --fast` end to end on a tiny zoo, and its report's numbers
checked against the episodes they come from."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.main import app
from evaluation.backend import EngineBackend, policy_backend
from evaluation.partners.report import rows_of
from evaluation.partners.suite import PartnersConfig, scenarios
from evaluation.prepare import train_tiny_zoo
from model_store.sql import SqlModelStore

FAST = PartnersConfig(
    aligned_pairs=1,
    non_aligned_pairs=1,
    pair_episodes=2,
    five_agent_sets=1,
    set_episodes=2,
    max_steps=30,
    partner_types=("other_seed", "scripted"),
)


@pytest.mark.slow
def test_fast_suite_writes_a_report_whose_tables_match_the_episodes(tmp_path: Path) -> None:
    drawn = [s for chosen in scenarios(FAST).values() for s in chosen]
    goals = sorted({g for s in drawn for g in s.goals})
    url = f"sqlite:///{tmp_path}/models.db"
    with SqlModelStore(url) as store:
        train_tiny_zoo(store, goals, goals, [])
    out = tmp_path / "report"
    args = ["eval", "--suite", "partners", "--fast", "--store-url", url, "--out", str(out)]
    args += ["--partner-types", "other_seed,scripted"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    report = (out / "REPORT.md").read_text()
    data = json.loads((out / "results.json").read_text())
    rows = data["rows"]
    types = {r["partner_type"] for r in rows}
    assert types == set(data["config"]["partner_types"])
    methods = {r["method"] for r in rows}
    assert methods == {"sl", "aail", "aail_bounded", "aail_budget"}
    for r in rows:  # every row of the tables is in the report with its own numbers
        assert f"| {r['units']} | {r['stranded']} |" in report
        if r["method"] == "sl":
            assert r["team_gain"] == 0.0 and r["stranded"] == 0
    assert "## Verdicts for" in report and "never strands" in report
    # the command a reader reruns names the zoo's folder and the output as variables, never the
    # folders of the machine the run was made on
    command = next(line for line in report.splitlines() if line.startswith("- Command:"))
    assert "sqlite:///$ZOO/models.db" in command and str(tmp_path) not in command
    # without the goal oracle: the same episodes for every method but AAIL-B, and the report
    # says how it was run
    blind = tmp_path / "blind"
    args[args.index(str(out))] = str(blind)
    result = CliRunner().invoke(app, [*args, "--no-goal-oracle"])
    assert result.exit_code == 0, result.output
    blind_report = (blind / "REPORT.md").read_text()
    assert "--no-goal-oracle" in blind_report and "without the goal oracle" in blind_report
    blind_rows = json.loads((blind / "results.json").read_text())["rows"]
    for r, b in zip(rows, blind_rows, strict=True):
        if r["method"] != "aail_bounded":  # Holm's family holds AAIL-B; NaN: no value
            assert json.dumps(_unadjusted(r)) == json.dumps(_unadjusted(b))


@pytest.mark.parametrize("flag", ["--no-goal-oracle", "--no-goal-monitor"])
@pytest.mark.parametrize(
    "more", [["--suite", "paper"], ["--suite", "partners", "--server", "http://127.0.0.1:9"]]
)
def test_the_goal_answer_flags_are_refused_where_they_cannot_act(
    more: list[str], flag: str
) -> None:
    """Only the partners suite's in-process engine can be told not to ask the environment or
    the monitors: a paper run or a server would silently ignore the flag."""
    result = CliRunner().invoke(app, ["eval", *more, "--fast", flag])
    assert result.exit_code == 2
    assert flag in result.output


def test_rows_are_computed_from_the_cells() -> None:
    from evaluation.config import Scenario
    from evaluation.partners.suite import PartnersResult
    from evaluation.rollout import CellResult

    def cell(method: str, ego: float, partner: float, success: list[bool]) -> CellResult:
        n = len(success)
        returns = np.array([[ego, partner]] * n)
        ok = np.array([[s, True] for s in success])
        return CellResult(
            Scenario("non_aligned:a2+b3", "a2", ("b3",), n, 1),
            method,
            returns,
            ok,
            ok,
            np.full(n, 10),
            np.asarray(ok.all(axis=1)),
            np.zeros((1, 2, 4)),
        )

    result = PartnersResult(PartnersConfig(methods=("sl", "aail")))
    result.cells = {
        "idle": {
            "non_aligned": [
                cell("sl", -10.0, -5.0, [True, True, False]),
                cell("aail", -11.0, -4.5, [True, False, True]),
            ]
        }
    }
    rows = {r.method: r for r in rows_of(result)}
    assert rows["aail"].stranded == 1  # SL ok and AAIL not: episode 1 only
    assert rows["aail"].regret_median == pytest.approx(0.1)
    assert rows["aail"].team_gain == pytest.approx(-0.5)
    assert rows["aail"].sets_below == 1


def test_the_spread_table_puts_each_zoo_in_its_column_and_refuses_other_configs() -> None:
    from evaluation.partners.spread import spread_markdown

    def run(gain: float, seed: int = 1) -> dict[str, object]:
        row = {"partner_type": "idle", "kind": "non_aligned", "stranded": 1, "help_kept": 0.5}
        config = {"seed": seed, "aligned_pairs": 1, "non_aligned_pairs": 1}
        config |= {"pair_episodes": 2, "five_agent_sets": 0}
        return {
            "config": config,
            "rows": [
                {**row, "method": "sl", "team_gain": 0.0},
                {**row, "method": "aail_bounded", "team_gain": gain},
            ],
        }

    text = spread_markdown([run(0.5), run(-0.25)], ["zoo0", "zoo10"])
    line = next(line for line in text.splitlines() if "AAIL-B" in line)
    assert "| +0.500 | -0.250 | -0.250 | +0.500 | 2 |" in line
    assert "| SL |" not in text  # SL is the reference, not a row
    with pytest.raises(ValueError, match=r"config\.seed"):
        spread_markdown([run(0.5), run(0.5, seed=2)], ["a", "b"])


def _unadjusted(row: dict) -> dict:
    return {k: v for k, v in row.items() if "holm" not in k}


@pytest.mark.parametrize(
    ("oracle", "monitors", "says"),
    [
        (True, True, "in-process engine"),
        (True, False, "the environment's answers where it gives them"),
        (False, True, "the goal monitors where registered"),
        (False, False, "neither: R1 on every row"),
    ],
)
def test_the_backend_says_how_aail_b_gets_its_answers(
    tmp_path: Path, oracle: bool, monitors: bool, says: str
) -> None:
    with SqlModelStore(f"sqlite:///{tmp_path}/models.db") as store:
        backend = policy_backend(None, store, goal_oracle=oracle, goal_monitors=monitors)
        assert says in backend.description
        assert isinstance(backend, EngineBackend)
        assert (backend.engine.goal_oracle, backend.engine.goal_monitors) == (oracle, monitors)
