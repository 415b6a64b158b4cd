"""`InferenceEngine.act_columns` and `ActColumns`: the same answer as `act`, as arrays."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from model_store.sql import SqlModelStore
from services.engine import ActColumns, ActRequest, InferenceEngine, InvalidRequest, PartnerSpec

CASES = {  # method, observation width, partners
    "aail, 2 partners": ("aail", 12, (PartnerSpec(2, goal="c"), PartnerSpec(1, goal="b3"))),
    "aail, goal_probs": ("aail", 8, (PartnerSpec(1, goal_probs={"b3": 0.4, "c": 0.6}),)),
    "nail": ("nail", 8, (PartnerSpec(1, goal="b3"),)),
    "sl with a partner": ("sl", 8, (PartnerSpec(1, goal="b3"),)),
    "sl alone": ("sl", 4, ()),
    "jl": ("jl", 12, (PartnerSpec(1, goal="b3"), PartnerSpec(2, goal="c1"))),
}


@pytest.fixture(scope="module")
def engine(_tiny_zoo_template: Path) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store:  # read-only use
        yield InferenceEngine(store)


def _request(method: str, width: int, partners: tuple[PartnerSpec, ...], rows: int) -> ActRequest:
    obs_BD = np.random.default_rng(rows).random((rows, width)) * 0.9
    return ActRequest("particle", "a2", obs_BD, partners, method=method, seed=13)  # type: ignore[arg-type]


@pytest.mark.parametrize("rows", [1, 6])
@pytest.mark.parametrize("case", CASES.values(), ids=list(CASES))
def test_columns_rows_equal_act(engine: InferenceEngine, case: tuple, rows: int) -> None:
    method, width, partners = case
    request = _request(method, width, partners, rows)
    columns = engine.act_columns(request)
    assert columns.rows() == engine.act(request)  # same values, same seeded samples
    assert len(columns) == rows and columns.method == method
    assert columns.probs.shape == (rows, 5) and columns.probs.dtype == np.float64
    assert columns.partner_weights.shape == (rows, len(partners))
    for name in ("actions", "greedy_actions"):
        assert getattr(columns, name).shape == (rows,)
        assert getattr(columns, name).dtype == np.int64
    assert (columns.greedy_actions == columns.probs.argmax(axis=1)).all()
    assert columns.models[0].role == ("joint" if method == "jl" else "task")


def test_from_results_round_trips(engine: InferenceEngine) -> None:
    method, width, partners = CASES["aail, 2 partners"]
    results = engine.act(_request(method, width, partners, 5))
    columns = ActColumns.from_results(results)
    assert columns.rows() == results
    again = ActColumns.from_results(columns.rows())
    for name in ("probs", "actions", "greedy_actions", "task_entropies", "task_weights"):
        assert np.array_equal(getattr(again, name), getattr(columns, name))
    no_partner = ActColumns.from_results(engine.act(_request("sl", 4, (), 2)))
    assert no_partner.partner_weights.shape == (2, 0)
    with pytest.raises(ValueError, match="at least one"):
        ActColumns.from_results([])


def test_rows_do_not_share_the_model_list(engine: InferenceEngine) -> None:
    method, width, partners = CASES["nail"]
    first, second = engine.act_columns(_request(method, width, partners, 2)).rows()
    assert first.models == second.models and first.models is not second.models


def test_errors_and_stats_are_acts(engine: InferenceEngine) -> None:
    before = engine.stats.snapshot()
    engine.act_columns(_request("aail", 8, (PartnerSpec(1, goal="b3"),), 4))
    engine.act_columns(_request("aail", 8, (PartnerSpec(1, goal="b3"),), 1))
    bad = ActRequest("particle", "a2", np.zeros((2, 7)))
    with pytest.raises(InvalidRequest) as info:
        engine.act_columns(bad)
    assert info.value.field == "observations"
    after = engine.stats
    assert (after.requests, after.rows, after.errors) == (
        before.requests + 2,
        before.rows + 5,
        before.errors + 1,
    )
