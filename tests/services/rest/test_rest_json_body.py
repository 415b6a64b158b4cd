"""`services.rest.json_body`: request bodies go through orjson, and through the standard parser
only where orjson would read them differently (NaN / Infinity literals, huge integers)."""

from __future__ import annotations

import json

import pytest

from services.rest import json_body

JSON = {"content-type": "application/json"}
BODY = {
    "env": "particle",
    "ego_goal": "a2",
    "observation": [0.1, 0.4, 0, 0, 0.7, 0.6, 0, 0],
    "partners": [{"index": 1, "goal": "b3"}],
    "seed": 3,
}


def _refuse_stdlib(monkeypatch: pytest.MonkeyPatch) -> list[bytes]:
    seen: list[bytes] = []

    def loads(body: bytes) -> object:
        seen.append(body)
        return json.loads(body)

    monkeypatch.setattr(json_body, "standard_loads", loads)
    return seen


def test_a_plain_body_is_parsed_by_orjson(act_client, monkeypatch) -> None:
    seen = _refuse_stdlib(monkeypatch)
    response = act_client.post("/v1/act", content=json.dumps(BODY), headers=JSON)
    assert response.status_code == 200 and not seen


def test_nan_literals_and_huge_integers_take_the_standard_parser(act_client, monkeypatch) -> None:
    seen = _refuse_stdlib(monkeypatch)
    nan = json.dumps(BODY).replace("0.1", "NaN", 1)
    assert act_client.post("/v1/act", content=nan, headers=JSON).status_code == 422
    huge = json.dumps({**BODY, "versions": {"particle/task/a2": 10**30}})  # orjson: 1e30
    answer = act_client.post("/v1/act", content=huge, headers=JSON)
    assert answer.status_code == 422
    assert answer.json()["field"] == "versions[particle/task/a2]"  # the engine's check
    assert len(seen) == 2


def test_malformed_json_is_still_a_422_naming_the_body(act_client) -> None:
    answer = act_client.post("/v1/act", content=b'{"env": "particle",', headers=JSON)
    assert answer.status_code == 422 and answer.json()["field"] == "body"


def test_only_scalars_outside_number_vectors_are_checked_for_huge_integers() -> None:
    assert json_body.has_huge_scalar({"versions": {"particle/task/a2": 1e30}})
    assert json_body.has_huge_scalar({"observed": [{"index": 1, "action": -1e19}]})
    assert not json_body.has_huge_scalar({"observations": [[1e30, 0.5], [0.1, 0.2]]})
    assert not json_body.has_huge_scalar({"seed": 2**62, "temperature": 0.05})


def test_a_lone_surrogate_is_a_422_not_a_string_nothing_can_encode(act_client) -> None:
    """`json.loads` reads `"\\ud800"` into a str that no UTF-8 encoder (database, log, answer)
    can write; orjson refuses it, and so does the fallback now: the body's 422."""
    lone = json.dumps(BODY).replace('"a2"', '"a2\\ud800"')
    answer = act_client.post("/v1/act", content=lone, headers=JSON)
    assert answer.status_code == 422 and answer.json()["field"] == "body"
    with pytest.raises(json.JSONDecodeError):
        json_body.parse_json(b'{"k\\udc00": 1}')  # in a key too
    assert json_body.has_lone_surrogate([{"a": ["x", "\ud800"]}])
    assert not json_body.has_lone_surrogate({"a": "\U0001f600 fine", "b": [1.5, None]})
    assert json_body.parse_json(b'{"a": "\\ud83d\\ude00", "n": NaN}')["a"] == "\U0001f600"


def test_a_body_nested_too_deeply_is_a_422(act_client) -> None:
    """orjson stops at depth 1024 and the standard parser then raised RecursionError (a 500
    where nothing caught it); both are the body's 422 now."""
    deep = b'{"observation": ' + b"[" * 50_000 + b"]" * 50_000 + b"}"
    answer = act_client.post("/v1/act", content=deep, headers=JSON)
    assert answer.status_code == 422 and answer.json()["field"] == "body"
    with pytest.raises(json.JSONDecodeError):
        json_body.parse_json(b"[" * 5_000 + b"]" * 5_000)
