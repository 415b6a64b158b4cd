"""`services.rest.number_rows`: a batch's rows (and states) read straight into an array take
exactly the bodies pydantic's `Matrix` (and `Tensor3`) takes, with the same values, and leave
every other body to it."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from pydantic import BaseModel, ValidationError

from services.rest.bounded import Matrix, Tensor3
from services.rest.number_rows import COMPILED, float_array
from services.rest.schemas import ActBatchBody

pytestmark = pytest.mark.skipif(not COMPILED, reason="services.rest._number_rows not built")


class _Reference(BaseModel):
    observations: Matrix


class _StatesReference(BaseModel):
    states: Tensor3


class _ListSubclass(list[list[float]]):
    pass


TAKEN: dict[str, list[list[Any]]] = {
    "floats": [[0.25, -1.5, 3e-310], [1e300, -0.0, 2.0]],
    "ints and floats": [[1, 2.5], [-3, 4]],
    "ints beyond 53 bits": [[2**60 + 1, -(2**70)], [0, 1]],
    "one number": [[7.0]],
    "NaN and infinities": [[float("nan"), float("inf")], [float("-inf"), 0.0]],
}
LEFT: dict[str, Any] = {  # values the compiled pass leaves to pydantic (accepted or not)
    "empty batch": [],
    "empty row": [[]],
    "ragged rows": [[1.0, 2.0], [3.0]],
    "a bool": [[True, 1.0]],
    "a numeric string": [["1.5", 2.0]],
    "a string": [[1.0, "x"]],
    "a None": [[None, 1.0]],
    "a row of numbers": [1.0, 2.0],
    "a tuple row": [(1.0, 2.0)],
    "a list subclass": _ListSubclass([[1.0]]),
    "an int beyond a double": [[10**400, 1.0]],
    "a float subclass": [[np.float64(1.0), 2.0]],
    "not a list": {"0": [1.0]},
}


@pytest.mark.parametrize("rows", TAKEN.values(), ids=list(TAKEN))
def test_taken_rows_equal_pydantic_values(rows: list[list[Any]]) -> None:
    array = float_array(rows, 2)
    assert isinstance(array, np.ndarray) and array.dtype == np.float64
    assert array.flags.c_contiguous and array.shape == (len(rows), len(rows[0]))
    expected = np.asarray(_Reference(observations=rows).observations, dtype=np.float64)
    np.testing.assert_array_equal(array, expected)  # NaN == NaN here, signs of zero compared
    assert np.array_equal(np.signbit(array), np.signbit(expected))


@pytest.mark.parametrize("value", LEFT.values(), ids=list(LEFT))
def test_everything_else_is_left_to_pydantic(value: Any) -> None:
    assert float_array(value, 2) is None


def _assert_like_pydantic(reference: type[BaseModel], field: str, value: Any, **extra: Any) -> None:
    """`ActBatchBody` takes `value` for `field` with the reference model's value, or refuses it
    with the same error locations."""
    body = {"env": "particle", "ego_goal": "a2", field: value, **extra}
    try:
        expected = getattr(reference.model_validate({field: value}), field)
    except ValidationError as refusal:
        with pytest.raises(ValidationError) as refused:
            ActBatchBody.model_validate(body)
        assert [e["loc"] for e in refused.value.errors()] == [e["loc"] for e in refusal.errors()]
        return
    assert getattr(ActBatchBody.model_validate(body), field) == expected


@pytest.mark.parametrize("value", LEFT.values(), ids=list(LEFT))
def test_the_body_model_accepts_and_refuses_as_pydantic_does(value: Any) -> None:
    _assert_like_pydantic(_Reference, "observations", value)


def test_a_large_batch_is_one_array() -> None:
    rows = np.random.default_rng(3).uniform(-1, 1, (512, 20)).tolist()
    observations = ActBatchBody.model_validate(
        {"env": "particle", "ego_goal": "a2", "observations": rows}
    ).observations
    assert isinstance(observations, np.ndarray)
    np.testing.assert_array_equal(observations, np.asarray(rows))


@pytest.mark.parametrize("fmt", ["rows", "columns"])
def test_both_ways_answer_a_batch_alike(act_client, fmt: str) -> None:
    """The same rows as numbers (the compiled pass) and with one written as a string (pydantic's
    way, which reads "0.5" as 0.5): the same answer, field for field."""
    rows = np.random.default_rng(4).uniform(-0.9, 0.9, (6, 8)).tolist()
    rows[0][0] = 0.5
    body = {
        "env": "particle",
        "ego_goal": "a2",
        "partners": [{"index": 1, "goal": "c"}],
        "method": "aail",
        "seed": 3,
        "format": fmt,
    }
    fast = act_client.post("/v1/act:batch", json={**body, "observations": rows})
    rows[0][0] = "0.5"
    slow = act_client.post("/v1/act:batch", json={**body, "observations": rows})
    assert fast.status_code == slow.status_code == 200, fast.text
    assert fast.json() == slow.json()


STATES_TAKEN: dict[str, list[list[list[Any]]]] = {
    "two states of two agents": [
        [[0.1, 0.2, 0, 1], [0.5, 0.5, 0.0, -1]],
        [[1, 2, 3, 4], [5, 6, 7, 8]],
    ],
    "one state of one agent": [[[0.25]]],
}
STATES_LEFT: dict[str, Any] = {
    "states of unequal agents": [[[0.1, 0.2]], [[0.1, 0.2], [0.3, 0.4]]],
    "an agent row of unequal length": [[[0.1, 0.2], [0.3]]],
    "a state of no agents": [[]],
    "a string": [[[0.1, "x"]]],
    "a bool": [[[0.1, False]]],
    "rows, not states": [[0.1, 0.2]],
}


@pytest.mark.parametrize("states", STATES_TAKEN.values(), ids=list(STATES_TAKEN))
def test_taken_states_equal_pydantic_values(states: list[list[list[Any]]]) -> None:
    array = float_array(states, 3)
    expected = np.asarray(_StatesReference(states=states).states, dtype=np.float64)
    assert isinstance(array, np.ndarray) and array.flags.c_contiguous
    np.testing.assert_array_equal(array, expected)
    assert array.shape == expected.shape


@pytest.mark.parametrize("value", STATES_LEFT.values(), ids=list(STATES_LEFT))
def test_other_states_are_left_to_pydantic(value: Any) -> None:
    assert float_array(value, 3) is None
    _assert_like_pydantic(_StatesReference, "states", value, ego_index=0)


def test_a_dimension_count_out_of_range_is_refused() -> None:
    with pytest.raises(ValueError, match=r"ndim: expected 1\.\.4"):
        float_array([[1.0]], 5)


def test_batch_states_answer_alike_both_ways(act_client) -> None:
    """Global states as numbers and with one written as a string: the same answer."""
    rng = np.random.default_rng(5)
    states = rng.uniform(-0.9, 0.9, (4, 2, 4)).tolist()
    for state in states:  # velocities within the speed cap
        for agent in state:
            agent[2] *= 0.3
            agent[3] *= 0.3
    states[0][0][0] = 0.5
    body = {
        "env": "particle",
        "ego_goal": "a2",
        "ego_index": 0,
        "partners": [{"index": 1, "goal": "c"}],
        "method": "aail",
        "seed": 3,
        "format": "columns",
    }
    fast = act_client.post("/v1/act:batch", json={**body, "states": states})
    states[0][0][0] = "0.5"
    slow = act_client.post("/v1/act:batch", json={**body, "states": states})
    assert fast.status_code == slow.status_code == 200, fast.text
    assert fast.json() == slow.json()
