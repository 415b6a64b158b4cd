"""The Open Inference Protocol (KServe v2, `services.oip`) against a real `coexist serve`:
Triton's official client (HTTP and gRPC, in a process of its own: `triton_calls.py`), every
method with its default arguments, never breaks on an answer (errors are its documented
`InferenceServerException`), and gets the same probabilities and action as `/v1/act` whether
the tensors travel as binary data or JSON; an unknown model or version is 404 / NOT_FOUND; bad
input is 400 (REST) or INVALID_ARGUMENT (gRPC) naming the input or parameter, in the protocol's
error shape `{"error": "<message>"}`."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import grpc
import httpx
import numpy as np
import pytest
from coexist_client import Client
from console_zoo import build_console_zoo
from fastapi.testclient import TestClient
from live_serve import serving
from pydantic import SecretStr
from replica_cluster import Server

from model_store.errors import StoreUnavailable
from services.app import create_app
from services.engine import InvalidRequest, ModelNotFound
from services.engine.errors import ModelUnavailable
from services.grpc_api.gen.inference import grpc_predict_v2_pb2 as pb
from services.oip.rest import _protocol_error, error_status
from services.settings import Settings

OBS = [0.1, 0.5, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0]
HERE = Path(__file__).resolve().parent
MISSING_VERSION = "999999999999"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    folder = tmp_path_factory.mktemp("oip")
    with serving(folder, build_console_zoo(folder / "models.db")) as server:
        yield server


@pytest.fixture(scope="module")
def triton(server: Server) -> dict[str, dict[str, Any]]:
    """What tritonclient answered to each call (`triton_calls.py`), per transport."""
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
    answers: dict[str, dict[str, Any]] = json.loads(done.stdout)
    return answers


def _infer(server: Server, body: dict[str, Any], model: str = "particle") -> httpx.Response:
    return httpx.post(f"{server.http_url}/v2/models/{model}/infer", json=body, timeout=10.0)


@pytest.mark.parametrize("transport", ["http", "grpc", "http_aio", "grpc_aio"])
def test_tritonclient_never_breaks_on_an_answer(
    triton: dict[str, dict[str, Any]], transport: str
) -> None:
    calls = triton[transport]
    assert len(calls) >= (30 if transport in ("http", "grpc") else 11)
    crashes = {name: c["crash"] for name, c in calls.items() if "crash" in c}
    assert crashes == {}


@pytest.mark.parametrize("transport", ["http_aio", "grpc_aio"])
def test_tritonclient_asyncio_clients_answer_as_the_others(
    triton: dict[str, dict[str, Any]], transport: str
) -> None:
    calls, sync = triton[transport], triton[transport.removesuffix("_aio")]
    assert calls["infer"] == sync["infer"]
    for name in ("live", "model_ready"):
        assert calls[name] == {"ok": True}, name
    for name in ("model_metadata", "infer_missing_version", "infer_missing_model"):
        assert calls[name].get("error") == sync[name].get("error"), name
    assert calls["infer_bad_goal"]["error"] == sync["infer_bad_goal"]["error"]
    assert calls["load_model"]["error"] == sync["load_model"]["error"]
    assert calls["model_config"]["ok"] == sync["model_config"]["ok"]


@pytest.mark.parametrize("transport", ["http", "grpc"])
def test_tritonclient_defaults_get_the_probabilities_of_v1_act(
    server: Server, triton: dict[str, dict[str, Any]], transport: str
) -> None:
    with Client(server.http_url) as client:
        want = client.act("particle", "a2", OBS, partners={1: "b3"}, seed=7)
    calls = triton[transport]
    got = calls["infer"]["ok"]  # binary inputs and outputs: the client's defaults
    assert got["probabilities"] == [pytest.approx(list(want.probs), abs=1e-12)]
    assert got["action"] == [want.action]
    assert got["greedy_action"] == [want.greedy_action]
    assert calls["infer_v1"]["ok"] == got
    assert calls["infer_one_output"]["ok"] == {"probabilities": got["probabilities"]}
    if transport == "http":  # the same inference with JSON tensors: equal to the last bit
        assert calls["infer_json"]["ok"] == got
    else:
        assert got == triton["http"]["infer"]["ok"]
    for name in ("live", "ready", "model_ready", "model_ready_v1"):
        assert calls[name] == {"ok": True}, name


@pytest.mark.parametrize("transport", ["http", "grpc"])
def test_tritonclient_errors_are_its_exception_with_the_protocols_status(
    triton: dict[str, dict[str, Any]], transport: str
) -> None:
    calls = triton[transport]
    not_found, invalid = (
        ("404", "400")
        if transport == "http"
        else (
            "StatusCode.NOT_FOUND",
            "StatusCode.INVALID_ARGUMENT",
        )
    )
    for name in (
        "model_metadata_missing_version",
        "model_config_missing_version",
        "infer_missing_version",
        "statistics_missing_version",
    ):
        assert calls[name]["error"] == not_found, name
        assert (
            "model_version" in calls[name]["message"] and MISSING_VERSION in calls[name]["message"]
        )
    for name in ("model_metadata_missing_model", "infer_missing_model"):
        assert calls[name]["error"] == not_found, name
        assert "model_name: unknown model 'nowhere'" in calls[name]["message"]
    expected = {
        "infer_bad_goal": "ego_goal: unknown goal 'zz'",
        "infer_bad_observation": "inputs[observation][0]: length 7",
        "infer_bad_parameter": "parameters.seed: expected an integer",
    }
    for name, message in expected.items():
        assert calls[name]["error"] == invalid, name
        assert message in calls[name]["message"], name
    if transport == "http":  # readiness is the status code: false, not an exception
        assert calls["model_ready_missing_version"] == {"ok": False}
        assert calls["model_ready_missing_model"] == {"ok": False}
        assert calls["load_model"]["error"] == calls["unload_model"]["error"] == "400"
        assert "registry" in calls["load_model"]["message"]
        unserved = ("trace_settings", "log_settings", "system_shared_memory", "cuda_shared_memory")
        for name in unserved:
            assert calls[name]["error"] == "404", name
    else:
        assert calls["model_ready_missing_version"]["error"] == not_found
        assert calls["model_ready_missing_model"]["error"] == not_found
        unserved = ("load_model", "unload_model", "trace_settings", "log_settings")
        for name in unserved:
            assert calls[name]["error"] == "StatusCode.UNIMPLEMENTED", name


@pytest.mark.parametrize("transport", ["http", "grpc"])
def test_tritonclient_reads_metadata_config_index_and_statistics(
    triton: dict[str, dict[str, Any]], transport: str
) -> None:
    calls = triton[transport]
    assert "binary_tensor_data" in calls["server_metadata"]["ok"]["extensions"]
    meta = calls["model_metadata"]["ok"]
    assert calls["model_metadata_v1"]["ok"] == meta
    shapes = {t["name"]: [int(d) for d in t["shape"]] for t in meta["inputs"] + meta["outputs"]}
    assert shapes == {
        "observation": [-1, -1],
        "ego_goal": [1],
        "partner_goals": [-1],
        "probabilities": [-1, 5],
        "action": [-1],
        "greedy_action": [-1],
    }
    config = calls["model_config"]["ok"]
    config = config.get("config", config)  # gRPC wraps it in a response message
    assert config["name"] == "particle"
    assert int(config.get("max_batch_size", 0)) == 0  # the dims are full shapes
    assert [int(d) for d in config["input"][0]["dims"]] == [-1, -1]
    goals = config["parameters"]["goals"]["string_value"].split(",")
    assert "a2" in goals and "b3" in goals and len(goals) == 35
    assert config["parameters"]["action_meanings"]["string_value"].split(",")[4] == "right"
    index = calls["repository_index"]["ok"]
    index = index.get("models", index) if isinstance(index, dict) else index
    assert {(m["name"], m["version"], m["state"]) for m in index} == {
        ("particle", "1", "READY"),
        ("cooking", "1", "READY"),
    }
    (stats,) = calls["model_statistics"]["ok"]["model_stats"]
    assert stats["name"] == "particle" and stats["version"] == "1"
    # the infers answered before (HTTP first, then gRPC: both counted by the one process)
    assert int(stats["inference_count"]) >= 4
    assert int(stats["inference_stats"]["success"]["count"]) >= 4
    assert int(stats["inference_stats"]["success"]["ns"]) > 0
    assert int(stats["inference_stats"]["fail"]["count"]) >= 2  # the bad goal and observation
    every = calls["statistics"]["ok"]["model_stats"]
    assert {s["name"] for s in every} == {"particle", "cooking"}


@pytest.mark.skipif(
    not os.environ.get("KSERVE_PYTHON"),
    reason="KServe's package is not in the dev extra (docs/client.md): set KSERVE_PYTHON to a "
    "Python that has it",
)
def test_kserve_clients_and_types(server: Server) -> None:
    """KServe's own v2 clients (`kserve_calls.py`) in a Python of their own."""
    done = subprocess.run(
        [
            os.environ["KSERVE_PYTHON"],
            str(HERE / "kserve_calls.py"),
            server.http_url,
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
    rest, grpc_calls = answers["rest"], answers["grpc"]
    crashes = [n for calls in answers.values() for n, c in calls.items() if "crash" in c]
    assert crashes == []
    got = rest["infer_json"]["ok"]
    assert rest["infer_binary"]["ok"] == got
    assert grpc_calls["infer"]["ok"] == grpc_calls["infer_v1"]["ok"] == got
    for calls in (rest, grpc_calls):
        assert calls["live"] == calls["ready"] == calls["model_ready"] == {"ok": True}
    assert rest["model_ready_missing_model"] == {"ok": False}
    assert rest["infer_bad_goal"]["error"] == "400"
    assert rest["infer_missing_model"]["error"] == "404"
    assert grpc_calls["infer_missing_version"]["error"] == "StatusCode.NOT_FOUND"
    assert grpc_calls["infer_bad_goal"]["error"] == "StatusCode.INVALID_ARGUMENT"


def test_a_version_that_does_not_exist_is_404_everywhere(server: Server) -> None:
    base = f"{server.http_url}/v2/models/particle/versions/{MISSING_VERSION}"
    body = {
        "parameters": {"ego_goal": "a2"},
        "inputs": [{"name": "observation", "datatype": "FP64", "shape": [8], "data": OBS}],
    }
    answers = [
        httpx.post(f"{base}/infer", json=body, timeout=10.0),
        httpx.get(f"{base}/ready"),
        httpx.get(base),
        httpx.get(f"{base}/config"),
        httpx.get(f"{base}/stats"),
    ]
    for response in answers:
        assert response.status_code == 404, response.request.url
        error = response.json()["error"]
        assert isinstance(error, str) and error.startswith("model_version: "), error
    good = httpx.post(
        f"{server.http_url}/v2/models/particle/versions/1/infer", json=body, timeout=10.0
    )
    assert good.status_code == 200 and good.json()["model_version"] == "1"


def test_rest_v2_metadata_and_health(server: Server) -> None:
    assert httpx.get(f"{server.http_url}/v2/health/live").json() == {"live": True}
    assert httpx.get(f"{server.http_url}/v2/health/ready").status_code == 200
    meta = httpx.get(f"{server.http_url}/v2").json()
    assert meta["name"] == "coexist" and meta["version"]
    model = httpx.get(f"{server.http_url}/v2/models/cooking").json()
    assert model["name"] == "cooking" and model["outputs"][0]["name"] == "probabilities"
    ready = httpx.get(f"{server.http_url}/v2/models/particle/ready")
    assert ready.status_code == 200 and ready.json() == {"name": "particle", "ready": True}
    missing = httpx.get(f"{server.http_url}/v2/models/nowhere/ready")
    assert missing.status_code == 404
    assert missing.json()["error"].startswith("model_name: unknown model 'nowhere'")
    index = httpx.post(f"{server.http_url}/v2/repository/index", json={"ready": True})
    assert [m["name"] for m in index.json()] == ["cooking", "particle"]


def test_goals_may_come_as_parameters_and_batches_as_rows(server: Server) -> None:
    body = {
        "id": "req-1",
        "parameters": {"ego_goal": "a2", "partner_goals": "b3", "seed": 7},
        "inputs": [
            {"name": "observation", "datatype": "FP64", "shape": [2, 8], "data": [*OBS, *OBS]}
        ],
    }
    response = _infer(server, body)
    assert response.status_code == 200, response.text
    assert response.json()["id"] == "req-1"
    outputs = {o["name"]: o for o in response.json()["outputs"]}
    assert outputs["probabilities"]["shape"] == [2, 5]
    assert outputs["action"]["shape"] == [2]
    with Client(server.http_url) as client:
        want = client.act_batch("particle", "a2", [OBS, OBS], partners={1: "b3"}, seed=7)
    flat = outputs["probabilities"]["data"]
    assert flat == pytest.approx([p for a in want for p in a.probs], abs=1e-12)


def _binary_body(observation: list[float], goal: bytes, outputs: Any) -> tuple[bytes, int]:
    obs = np.asarray(observation, dtype="<f8").tobytes()
    goal_raw = struct.pack("<I", len(goal)) + goal
    header = {
        "parameters": {"partner_goals": "b3", "seed": 7},
        "inputs": [
            {
                "name": "observation",
                "datatype": "FP64",
                "shape": [1, len(observation)],
                "parameters": {"binary_data_size": len(obs)},
            },
            {
                "name": "ego_goal",
                "datatype": "BYTES",
                "shape": [1],
                "parameters": {"binary_data_size": len(goal_raw)},
            },
        ],
        "outputs": outputs,
    }
    text = json.dumps(header).encode()
    return text + obs + goal_raw, len(text)


def test_binary_tensor_data_in_and_out_equals_json(server: Server) -> None:
    body, length = _binary_body(
        OBS,
        b"a2",
        [
            {"name": "greedy_action"},  # JSON: no parameter, no binary_data_output
            {"name": "probabilities", "parameters": {"binary_data": True}},
        ],
    )
    response = httpx.post(
        f"{server.http_url}/v2/models/particle/infer",
        content=body,
        headers={"Inference-Header-Content-Length": str(length)},
        timeout=10.0,
    )
    assert response.status_code == 200, response.text
    header_length = int(response.headers["inference-header-content-length"])
    header = json.loads(response.content[:header_length])
    greedy, probs = header["outputs"]
    assert [greedy["name"], probs["name"]] == ["greedy_action", "probabilities"]
    assert probs["parameters"] == {"binary_data_size": 5 * 8} and "data" not in probs
    binary = np.frombuffer(response.content[header_length:], dtype="<f8")
    as_json = _infer(
        server,
        {
            "parameters": {"ego_goal": "a2", "partner_goals": "b3", "seed": 7},
            "inputs": [{"name": "observation", "datatype": "FP64", "shape": [1, 8], "data": OBS}],
        },
    ).json()
    json_outputs = {o["name"]: o for o in as_json["outputs"]}
    assert binary.tolist() == json_outputs["probabilities"]["data"]  # equal to the last bit
    assert greedy["data"] == json_outputs["greedy_action"]["data"]


@pytest.mark.parametrize(
    ("header_length", "cut", "message"),
    [
        ("100000", 0, "Inference-Header-Content-Length: expected the JSON part's length"),
        ("x", 0, "Inference-Header-Content-Length"),
        (None, 3, "inputs[ego_goal].parameters.binary_data_size: "),
        (None, -4, "body: 4 bytes of binary data that no input's size claims"),
    ],
)
def test_malformed_binary_data_is_a_400_naming_it(
    server: Server, header_length: str | None, cut: int, message: str
) -> None:
    body, length = _binary_body(OBS, b"a2", None)
    if cut > 0:
        body = body[:-cut]
    elif cut < 0:
        body = body + b"\0" * -cut
    response = httpx.post(
        f"{server.http_url}/v2/models/particle/infer",
        content=body,
        headers={"Inference-Header-Content-Length": header_length or str(length)},
        timeout=10.0,
    )
    assert response.status_code == 400, response.text
    assert response.json()["error"].startswith(message)


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
                "parameters": {"ego_goal": "a2", "sequence_id": 3},
            },
            "parameters.sequence_id",
        ),
        (
            {
                "inputs": [{"name": "observation", "datatype": "FP32", "shape": [8], "data": OBS}],
                "parameters": {"ego_goal": "a2"},
                "outputs": [{"name": "action", "parameters": {"classification": 2}}],
            },
            "outputs[action].parameters.classification",
        ),
        (
            {
                "inputs": [{"name": "observation", "datatype": "FP32", "shape": [8], "data": OBS}],
                "parameters": {"ego_goal": "a2"},
                "outputs": [{"name": "logits"}],
            },
            "outputs[logits]",
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
def test_bad_rest_input_is_a_400_naming_the_field(
    server: Server, body: dict[str, Any], field: str
) -> None:
    response = _infer(server, body)
    assert response.status_code == 400, response.text
    error = response.json()["error"]
    assert isinstance(error, str) and error.startswith(f"{field}: "), error


def test_a_lone_surrogate_or_deep_nesting_is_a_400(server: Server) -> None:
    """`"id": "x\\ud800"` is a str nothing can encode (echoed back, it was a 500), and a body
    nested too deeply is what the standard parser met with a RecursionError."""
    body = {
        "id": "x",
        "parameters": {"ego_goal": "a2", "partner_goals": "b3"},
        "inputs": [{"name": "observation", "datatype": "FP64", "shape": [1, 8], "data": OBS}],
    }
    raw = json.dumps(body).replace('"x"', '"x\\ud800"')
    deep = b"[" * 50_000 + b"]" * 50_000
    for content in (raw.encode(), deep):
        response = httpx.post(
            f"{server.http_url}/v2/models/particle/infer",
            content=content,
            headers={"content-type": "application/json"},
            timeout=10.0,
        )
        assert response.status_code == 400, response.text
        assert response.json()["error"].startswith("body: ")


def test_unknown_routes_and_methods_answer_in_the_protocols_shape(server: Server) -> None:
    for response, status in (
        (httpx.get(f"{server.http_url}/v2/logging"), 404),
        (httpx.get(f"{server.http_url}/v2/models/particle/infer"), 405),
        (httpx.post(f"{server.http_url}/v2/health/live"), 405),
    ):
        assert response.status_code == status, response.request.url
        assert isinstance(response.json()["error"], str) and response.json()["error"]


def test_the_token_gate_and_the_body_limit_answer_in_the_protocols_shape() -> None:
    """Layers in front of the v2 routes (no store or engine needed: neither lets a request
    through), as tritonclient sees them without a token or with too large a body."""
    settings = Settings(
        admin_token=SecretStr("t0ken-for-the-tests-0123"),
        read_token=SecretStr("read-t0ken-for-the-tests"),
        max_body_bytes=1024,
        grpc_enabled=False,
    )
    client = TestClient(create_app(settings))  # no `with`: the lifespan (the store) never runs
    denied = client.get("/v2/models/particle")
    assert denied.status_code == 401
    assert isinstance(denied.json()["error"], str) and denied.json()["error"]
    big = client.post(
        "/v2/models/particle/infer",
        content=b"{" + b" " * 4096 + b"}",
        headers={"Authorization": "Bearer read-t0ken-for-the-tests"},
    )
    assert big.status_code == 413
    assert "1024" in big.json()["error"]
    v1 = client.get("/v1/envs")  # other paths keep their own shape: problem details
    assert v1.headers["content-type"] == "application/problem+json"
    assert v1.json()["code"] == "unauthorized" and "error" not in v1.json()
    assert denied.headers["content-type"] == "application/json"


@pytest.mark.parametrize(
    ("status", "body", "want"),
    [
        (404, b'{"detail": "Not Found"}', (404, "no such v2 route")),
        (  # the problem details every other path answers (services.problems)
            422,
            b'{"type": "/problems/invalid_request", "title": "Invalid request", "status": 422,'
            b' "detail": "seed: bad", "code": "invalid_request", "field": "seed"}',
            (400, "seed: bad"),
        ),
        (
            404,
            b'{"type": "/problems/not_found", "title": "Not found", "status": 404,'
            b' "detail": "Not Found", "code": "not_found", "field": null}',
            (404, "no such v2 route"),
        ),
        (
            422,
            b'{"error": {"code": "x", "message": "seed: bad", "field": "seed"}}',
            (400, "seed: bad"),
        ),
        (
            401,
            b'{"type": "about:blank", "title": "Unauthorized", "status": 401}',
            (401, "Unauthorized"),
        ),
        (500, b"Internal Server Error", (500, "Internal Server Error")),
        (413, b"", (413, "HTTP 413")),
        (400, b'{"error": "already fine"}', (400, "already fine")),
    ],
)
def test_error_bodies_of_other_layers_become_the_protocols(
    status: int, body: bytes, want: tuple[int, str]
) -> None:
    got_status, got_body = _protocol_error(status, body)
    error = json.loads(got_body)["error"]
    assert got_status == want[0] and isinstance(error, str) and error.startswith(want[1])


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
        request.parameters["method"].string_param = "sl"
        request.model_version = MISSING_VERSION  # the version is honoured, not ignored
        with pytest.raises(grpc.RpcError) as info:
            call(request, timeout=10)
        assert info.value.code() == grpc.StatusCode.NOT_FOUND
        request.model_version = "1"
        assert call(request, timeout=10).model_version == "1"


def test_error_statuses_follow_the_protocol() -> None:
    assert error_status(InvalidRequest("inputs[observation]", "bad")) == 400
    assert error_status(ModelNotFound("particle", "2", field="model_version")) == 404
    assert error_status(ModelUnavailable(None, "cannot load")) == 503
    assert error_status(StoreUnavailable("database is down")) == 503
