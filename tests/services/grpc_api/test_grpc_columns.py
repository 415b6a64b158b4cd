"""gRPC ActBatch's columnar form: `observation_matrix` input and `BATCH_FORMAT_COLUMNS` answers
against a real server; the same values as the rows form, matrix errors naming the field."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import grpc
import numpy as np
import pytest
from grpc_live_server import MAX_BATCH, LiveServer, live_grpc_server

from model_store.sql import SqlModelStore
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

COLUMNS, ROWS = pb.BATCH_FORMAT_COLUMNS, pb.BATCH_FORMAT_ROWS
OBS_BD = np.random.default_rng(0).random((9, 12)) * np.tile([1.0, 1.0, 0.2, 0.2], 3)
PARTNERS = [pb.PartnerSpec(index=2, goal="c"), pb.PartnerSpec(index=1, goal="d4")]


@pytest.fixture(scope="module")
def live(_tiny_zoo_template: Any) -> Iterator[LiveServer]:
    with SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store, live_grpc_server(store) as live:
        yield live


def matrix(obs_BD: np.ndarray) -> pb.Matrix:
    return pb.Matrix(rows=obs_BD.shape[0], cols=obs_BD.shape[1], values=obs_BD.ravel())


def batch(**changes: Any) -> pb.ActBatchRequest:
    fields: dict[str, Any] = {
        "env": "particle",
        "ego_goal": "b3",
        "observations": [pb.Vector(values=r) for r in OBS_BD],
        "partners": PARTNERS,
        "method": "aail",
        "temperature": 0.3,
        "seed": 11,
    }
    fields.update(changes)
    return pb.ActBatchRequest(**fields)


def assert_columns_are_rows(
    columns: pb.ActColumns, results: Any, partner_indices: list[int]
) -> None:
    rows, n_actions = columns.rows, columns.n_actions
    assert rows == len(results) and n_actions == 5
    probs = np.array(columns.probs).reshape(rows, n_actions)
    assert probs.tolist() == [list(r.probs) for r in results]
    assert list(columns.actions) == [r.action for r in results]
    assert list(columns.greedy_actions) == [r.greedy_action for r in results]
    assert list(columns.action_meanings) == [r.action_meaning for r in results]
    assert list(columns.task_entropies) == [r.diagnostics.task_entropy for r in results]
    assert list(columns.task_weights) == [r.diagnostics.task_weight for r in results]
    assert list(columns.partner_indices) == partner_indices
    weights = np.array(columns.partner_weights).reshape(rows, len(partner_indices))
    for b, result in enumerate(results):
        assert [(w.index, w.weight) for w in result.diagnostics.partner_weights] == list(
            zip(partner_indices, weights[b].tolist(), strict=True)
        )
        assert list(result.models) == list(columns.models) and result.method == columns.method


@pytest.mark.parametrize("rows", [1, 9])
@pytest.mark.parametrize("method", ["aail", "nail", "sl"])
def test_columns_equal_rows(live: LiveServer, method: str, rows: int) -> None:
    obs = [pb.Vector(values=r) for r in OBS_BD[:rows]]
    by_rows = live.stub.ActBatch(batch(observations=obs, method=method))
    by_columns = live.stub.ActBatch(batch(observations=obs, method=method, format=COLUMNS))
    assert not by_rows.HasField("columns") and len(by_rows.results) == rows
    assert len(by_columns.results) == 0
    assert_columns_are_rows(by_columns.columns, by_rows.results, [2, 1])


def test_observation_matrix_equals_observations(live: LiveServer) -> None:
    for fmt in (ROWS, COLUMNS):
        by_vectors = live.stub.ActBatch(batch(format=fmt))
        by_matrix = live.stub.ActBatch(
            batch(observations=[], observation_matrix=matrix(OBS_BD), format=fmt)
        )
        assert by_matrix == by_vectors


def test_states_and_no_partners_in_columns(live: LiveServer) -> None:
    agents = OBS_BD[:4, :8].reshape(4, 2, 4)
    states = [pb.State(agents=[pb.Vector(values=a) for a in s]) for s in agents]
    fields: dict[str, Any] = {
        "observations": [],
        "states": states,
        "ego_index": 0,
        "partners": [],
        "method": "sl",
    }
    by_columns = live.stub.ActBatch(batch(**fields, format=COLUMNS))
    assert_columns_are_rows(by_columns.columns, live.stub.ActBatch(batch(**fields)).results, [])
    assert len(by_columns.columns.partner_weights) == 0


def _field_of(err: grpc.RpcError) -> str | None:
    return dict(err.trailing_metadata() or ()).get("coexist-field")


NAN_ROW = OBS_BD[:3].copy()
NAN_ROW[2, 5] = float("nan")
ERROR_CASES = [
    ("rows 0", pb.Matrix(rows=0, cols=12), "observation_matrix.rows"),
    ("negative rows", pb.Matrix(rows=-2, cols=12, values=[0.0] * 24), "observation_matrix.rows"),
    ("cols 0", pb.Matrix(rows=3, cols=0), "observation_matrix.cols"),
    ("too few values", pb.Matrix(rows=2, cols=12, values=OBS_BD[0]), "observation_matrix.values"),
    ("too many values", pb.Matrix(rows=1, cols=4, values=OBS_BD[0]), "observation_matrix.values"),
    ("width fits no agent count", matrix(OBS_BD[:, :7]), "observation_matrix"),
    ("oversized", matrix(np.zeros((MAX_BATCH + 1, 12))), "observation_matrix"),
    ("NaN in row 2", matrix(NAN_ROW), "observation_matrix[2]"),
]


@pytest.mark.parametrize("fmt", [ROWS, COLUMNS], ids=["rows", "columns"])
@pytest.mark.parametrize(
    ("matrix_", "field"), [c[1:] for c in ERROR_CASES], ids=[c[0] for c in ERROR_CASES]
)
def test_matrix_errors_name_the_field(
    live: LiveServer, matrix_: pb.Matrix, field: str, fmt: int
) -> None:
    with pytest.raises(grpc.RpcError) as info:
        live.stub.ActBatch(batch(observations=[], observation_matrix=matrix_, format=fmt))
    assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert _field_of(info.value) == field
    assert info.value.details().startswith(f"{field}: ")


STATE = pb.State(agents=[pb.Vector(values=OBS_BD[0, :4]), pb.Vector(values=OBS_BD[0, 4:8])])
TWO_INPUTS = [
    ("matrix and observations", {"observation_matrix": matrix(OBS_BD)}, "observation_matrix"),
    (
        "matrix and states",
        {"observations": [], "states": [STATE], "observation_matrix": matrix(OBS_BD)},
        "observation_matrix",
    ),
    ("observations and states", {"states": [STATE]}, "observations"),
    ("an empty matrix and observations", {"observation_matrix": pb.Matrix()}, "observation_matrix"),
]


@pytest.mark.parametrize(
    ("changes", "field"), [c[1:] for c in TWO_INPUTS], ids=[c[0] for c in TWO_INPUTS]
)
def test_two_inputs_at_once_are_refused(
    live: LiveServer, changes: dict[str, Any], field: str
) -> None:
    with pytest.raises(grpc.RpcError) as info:
        live.stub.ActBatch(batch(format=COLUMNS, **changes))
    assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert _field_of(info.value) == field and "exactly one of" in info.value.details()


def test_unknown_format_is_refused(live: LiveServer) -> None:
    with pytest.raises(grpc.RpcError) as info:
        live.stub.ActBatch(batch(format=7))
    assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert _field_of(info.value) == "format"
