"""The committed reports/mpe2_landmarks says what its data says: every mean, interval and test
of results.json is what `evaluation.stats` computes from its per-pair means, and REPORT.md is
what `evaluation.pairs.report` writes from results.json."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from evaluation.pairs.report import MEASURES, NON_INFERIORITY_MARGIN, REFERENCE, write_report
from evaluation.stats import paired_ci, tost_paired, wilcoxon_p

REPORT = Path(__file__).resolve().parents[3] / "reports" / "mpe2_landmarks"
KEYS = ("pairs", "default", "methods", "versus_sl", "default_success_non_inferiority")


@pytest.fixture(scope="module")
def results() -> dict:
    return json.loads((REPORT / "results.json").read_text())


def test_the_figures_are_the_statistics_of_the_per_pair_means(results: dict) -> None:
    methods = results["methods"]
    n = len(results["pairs"])
    for measure in MEASURES:
        sl = np.array(methods[REFERENCE][measure]["per_pair"])
        for name, row in methods.items():
            values = np.array(row[measure]["per_pair"])
            assert values.size == n
            assert row[measure]["mean"] == pytest.approx(values.mean())
            ci = paired_ci(values, np.zeros(n))
            assert row[measure]["ci95"] == pytest.approx([ci.low, ci.high])
            if name != REFERENCE:
                test = results["versus_sl"][measure][name]
                assert test["diff"] == pytest.approx((values - sl).mean())
                assert test["p"] == pytest.approx(wilcoxon_p(values, sl))
    default = results["default"]
    tost = tost_paired(
        methods[default]["ego_success"]["per_pair"],
        methods[REFERENCE]["ego_success"]["per_pair"],
        margin_fraction=NON_INFERIORITY_MARGIN,
    )
    assert results["default_success_non_inferiority"]["p_lower"] == pytest.approx(tost.p_lower)


def test_the_report_is_what_its_results_write(results: dict, tmp_path: Path) -> None:
    written = write_report(
        {key: results[key] for key in KEYS},
        tmp_path,
        env=results["env"],
        settings=results["settings"],
        command=results["command"],
        backend="in-process engine",
    )
    assert written.read_text() == (REPORT / "REPORT.md").read_text()
