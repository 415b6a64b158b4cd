"""The Open Inference Protocol (KServe v2, `services.oip`) against a real `coexist serve`:
Triton's official client (HTTP and gRPC, in a process of its own: `triton_calls.py`) gets the
same probabilities and action as `/v1/act`; bad input is a 4xx (REST) or INVALID_ARGUMENT (gRPC)
naming the input or parameter."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import grpc
import httpx
import pytest
from coexist_client import Client
from console_zoo import build_console_zoo
from live_serve import serving
from replica_cluster import Server

from services.grpc_api.gen.inference import grpc_predict_v2_pb2 as pb

OBS = [0.1, 0.5, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    folder = tmp_path_factory.mktemp("oip")
    with serving(folder, build_console_zoo(folder / "models.db")) as server:
        yield server


def _infer(server: Server, body: dict[str, Any], model: str = "particle") -> httpx.Response:
    return httpx.post(f"{server.http_url}/v2/models/{model}/infer", json=body, timeout=10.0)


def test_tritonclient_gets_the_probabilities_of_v1_act(server: Server) -> None:
    with Client(server.http_url) as client:
        want = client.act("particle", "a2", OBS, partners={1: "b3"}, seed=7)
    done = subprocess.run(
        [
            sys.executable,
            str(HERE / "triton_calls.py"),
            server.http_url.removeprefix("http://"),
            server.grpc_target,
            json.dumps(OBS),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    answers = json.loads(done.stdout)
    for transport in ("http", "grpc"):
        got = answers[transport]
        assert got["live"] and got["ready"] and got["model_ready"], transport
        assert got["probabilities"] == [pytest.approx(list(want.probs), abs=1e-12)], transport
        assert got["action"] == [want.action], transport
        names = [t["name"] for t in got["metadata"]["inputs"]]
        assert names == ["observation", "ego_goal", "partner_goals"], transport
    bad = answers["grpc_bad"]
    assert bad is not None and bad["status"] == "StatusCode.INVALID_ARGUMENT"
    assert "observation" in bad["message"]


def test_rest_v2_metadata_and_health(server: Server) -> None:
    assert httpx.get(f"{server.http_url}/v2/health/live").json() == {"live": True}
    assert httpx.get(f"{server.http_url}/v2/health/ready").status_code == 200
    meta = httpx.get(f"{server.http_url}/v2").json()
    assert meta["name"] == "coexist" and meta["version"]
    model = httpx.get(f"{server.http_url}/v2/models/cooking").json()
    assert model["name"] == "cooking" and model["outputs"][0]["name"] == "probabilities"
    assert httpx.get(f"{server.http_url}/v2/models/nowhere/ready").status_code == 400


def test_goals_may_come_as_parameters_and_batches_as_rows(server: Server) -> None:
    body = {
        "parameters": {"ego_goal": "a2", "partner_goals": "b3", "seed": 7},
        "inputs": [
            {"name": "observation", "datatype": "FP64", "shape": [2, 8], "data": [*OBS, *OBS]}
        ],
    }
    response = _infer(server, body)
    assert response.status_code == 200, response.text
    outputs = {o["name"]: o for o in response.json()["outputs"]}
    assert outputs["probabilities"]["shape"] == [2, 5]
    assert outputs["action"]["shape"] == [2]
    with Client(server.http_url) as client:
        want = client.act_batch("particle", "a2", [OBS, OBS], partners={1: "b3"}, seed=7)
    flat = outputs["probabilities"]["data"]
    assert flat == pytest.approx([p for a in want for p in a.probs], abs=1e-12)


@pytest.mark.parametrize(
    ("body", "field"),
    [
        (
            {
                "inputs": [
                    {"name": "observation", "datatype": "FP32", "shape": [7], "data": OBS[:7]}
                ],
                "parameters": {"ego_goal": "a2"},
            },
            "inputs[observation][0]",
        ),
        (
            {"inputs": [{"name": "observation", "datatype": "FP32", "shape": [8], "data": OBS}]},
            "inputs[ego_goal]",
        ),
        (
            {"inputs": [{"name": "obs", "datatype": "FP32", "shape": [8], "data": OBS}]},
            "inputs[obs]",
        ),
        (
            {
                "inputs": [{"name": "observation", "datatype": "FP32", "shape": [8], "data": OBS}],
                "parameters": {"ego_goal": "a2", "seed": "x"},
            },
            "parameters.seed",
        ),
        (
            {
                "inputs": [{"name": "observation", "datatype": "FP32", "shape": [8], "data": OBS}],
                "parameters": {"ego_goal": "zz"},
            },
            "ego_goal",
        ),
        (
            {
                "inputs": [{"name": "observation", "datatype": "FP32", "shape": [9], "data": OBS}],
                "parameters": {"ego_goal": "a2"},
            },
            "inputs[observation]",
        ),
        ({"inputs": "nope"}, "inputs"),
    ],
)
def test_bad_rest_input_is_a_4xx_naming_the_field(
    server: Server, body: dict[str, Any], field: str
) -> None:
    response = _infer(server, body)
    assert 400 <= response.status_code < 500, response.text
    assert response.json()["error"]["field"] == field


def test_a_lone_surrogate_in_the_body_is_a_422(server: Server) -> None:
    """`"id": "x\\ud800"` parsed into a str nothing can encode (echoed back: a 500), and a body
    nested too deeply for the standard parser."""
    body = {
        "id": "x",
        "parameters": {"ego_goal": "a2", "partner_goals": "b3"},
        "inputs": [{"name": "observation", "datatype": "FP64", "shape": [1, 8], "data": OBS}],
    }
    raw = json.dumps(body).replace('"x"', '"x\\ud800"')
    response = httpx.post(
        f"{server.http_url}/v2/models/particle/infer",
        content=raw,
        headers={"content-type": "application/json"},
        timeout=10.0,
    )
    assert response.status_code == 422, response.text
    assert response.json()["error"]["field"] == "body"
    deep = b"[" * 50_000 + b"]" * 50_000  # the standard parser's RecursionError was a 500 too
    response = httpx.post(
        f"{server.http_url}/v2/models/particle/infer",
        content=deep,
        headers={"content-type": "application/json"},
        timeout=10.0,
    )
    assert response.status_code == 422, response.text


def test_bad_grpc_input_is_invalid_argument_naming_the_field(server: Server) -> None:
    request = pb.ModelInferRequest(model_name="particle")
    request.parameters["ego_goal"].string_param = "a2"
    tensor = request.inputs.add(name="observation", datatype="FP64", shape=[8])
    tensor.contents.fp64_contents.extend(OBS)
    request.parameters["method"].string_param = "nothing"
    with grpc.insecure_channel(server.grpc_target) as channel:
        call = channel.unary_unary(
            "/inference.GRPCInferenceService/ModelInfer",
            request_serializer=pb.ModelInferRequest.SerializeToString,
            response_deserializer=pb.ModelInferResponse.FromString,
        )
        with pytest.raises(grpc.RpcError) as info:
            call(request, timeout=10)
    assert info.value.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert dict(info.value.trailing_metadata() or ())["coexist-field"] == "method"
