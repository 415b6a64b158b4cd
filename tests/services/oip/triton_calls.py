"""Run as a script by test_open_inference.py: Triton's official client (`tritonclient`, HTTP and
gRPC) against a coexist server, every client method with its default arguments, printing what
each answered as one JSON object.

    python triton_calls.py HTTP_HOST:PORT GRPC_HOST:PORT OBSERVATION_JSON

Each call is recorded as `{"ok": value}`, `{"error": status, "message": str(exception)}` for
the client's documented `InferenceServerException` (its `str()` is taken: that is where a
non-string error body made the client itself raise `TypeError`), or `{"crash": "Type: ..."}`
for any other exception, which the test counts and wants none of.

It runs in a process of its own because `tritonclient.grpc` and the server's generated v2 code
both define the protocol's messages (package `inference`) in protobuf's default pool, which
refuses a second definition: a real client never shares the server's process anyway.
"""

from __future__ import annotations

import asyncio
import json
import sys
from collections.abc import Callable
from typing import Any

import numpy as np
import tritonclient.grpc as triton_grpc
import tritonclient.grpc.aio as triton_grpc_aio
import tritonclient.http as triton_http
import tritonclient.http.aio as triton_http_aio
from tritonclient.utils import InferenceServerException

OUTPUTS = ("probabilities", "action", "greedy_action")
MISSING_VERSION = "999999999999"


def call(fn: Callable[[], Any]) -> dict[str, Any]:
    try:
        value = fn()
    except InferenceServerException as err:
        return {"error": err.status(), "message": str(err)}
    except Exception as err:  # what the test forbids: the client breaking on an answer
        return {"crash": f"{type(err).__name__}: {err}"}
    return {"ok": value}


def inputs(
    module: Any, observation: list[float], binary: bool = True, goal: str = "a2"
) -> list[Any]:
    """The three inputs, binary data by default (the client's own default), or JSON."""
    obs = module.InferInput("observation", [1, len(observation)], "FP32")
    ego = module.InferInput("ego_goal", [1], "BYTES")
    partners = module.InferInput("partner_goals", [1], "BYTES")
    kwargs = {} if binary else {"binary_data": False}
    obs.set_data_from_numpy(np.asarray([observation], dtype=np.float32), **kwargs)
    ego.set_data_from_numpy(np.asarray([goal.encode()], dtype=np.object_), **kwargs)
    partners.set_data_from_numpy(np.asarray([b"b3"], dtype=np.object_), **kwargs)
    return [obs, ego, partners]


def outputs_of(result: Any) -> dict[str, Any]:
    answered = {name: result.as_numpy(name) for name in OUTPUTS}
    return {name: array.tolist() for name, array in answered.items() if array is not None}


def http_calls(target: str, observation: list[float]) -> dict[str, Any]:
    client = triton_http.InferenceServerClient(target)
    params = {"seed": 7}

    def infer(**kwargs: Any) -> Callable[[], Any]:
        kwargs.setdefault("inputs", inputs(triton_http, observation))
        return lambda: outputs_of(client.infer(kwargs.pop("model", "particle"), **kwargs))

    json_outputs = [triton_http.InferRequestedOutput(n, binary_data=False) for n in OUTPUTS]
    return {
        "live": call(client.is_server_live),
        "ready": call(client.is_server_ready),
        "model_ready": call(lambda: client.is_model_ready("particle")),
        "model_ready_v1": call(lambda: client.is_model_ready("particle", "1")),
        "model_ready_missing_version": call(
            lambda: client.is_model_ready("particle", MISSING_VERSION)
        ),
        "model_ready_missing_model": call(lambda: client.is_model_ready("nowhere")),
        "server_metadata": call(client.get_server_metadata),
        "model_metadata": call(lambda: client.get_model_metadata("particle")),
        "model_metadata_v1": call(lambda: client.get_model_metadata("particle", "1")),
        "model_metadata_missing_version": call(
            lambda: client.get_model_metadata("particle", MISSING_VERSION)
        ),
        "model_metadata_missing_model": call(lambda: client.get_model_metadata("nowhere")),
        "model_config": call(lambda: client.get_model_config("particle")),
        "model_config_missing_version": call(
            lambda: client.get_model_config("particle", MISSING_VERSION)
        ),
        "repository_index": call(client.get_model_repository_index),
        # binary inputs, binary outputs (`binary_data_output`): the client's defaults
        "infer": call(infer(parameters=params)),
        "infer_v1": call(infer(parameters=params, model_version="1")),
        "infer_json": call(
            infer(
                inputs=inputs(triton_http, observation, binary=False),
                outputs=json_outputs,
                parameters=params,
            )
        ),
        "infer_one_output": call(
            infer(outputs=[triton_http.InferRequestedOutput("probabilities")], parameters=params)
        ),
        "infer_missing_version": call(infer(parameters=params, model_version=MISSING_VERSION)),
        "infer_missing_model": call(infer(model="nowhere")),
        "infer_bad_goal": call(infer(inputs=inputs(triton_http, observation, goal="zz"))),
        "infer_bad_observation": call(infer(inputs=inputs(triton_http, observation[:-1]))),
        "infer_bad_parameter": call(infer(parameters={"seed": "x"})),
        "statistics": call(client.get_inference_statistics),
        "model_statistics": call(lambda: client.get_inference_statistics("particle")),
        "statistics_missing_version": call(
            lambda: client.get_inference_statistics("particle", MISSING_VERSION)
        ),
        "load_model": call(lambda: client.load_model("particle")),
        "unload_model": call(lambda: client.unload_model("particle")),
        "trace_settings": call(client.get_trace_settings),
        "log_settings": call(client.get_log_settings),
        "system_shared_memory": call(client.get_system_shared_memory_status),
        "cuda_shared_memory": call(client.get_cuda_shared_memory_status),
    }


def grpc_calls(target: str, observation: list[float]) -> dict[str, Any]:
    client = triton_grpc.InferenceServerClient(target)
    params = {"seed": 7}

    def infer(**kwargs: Any) -> Callable[[], Any]:
        kwargs.setdefault("inputs", inputs(triton_grpc, observation))
        return lambda: outputs_of(client.infer(kwargs.pop("model", "particle"), **kwargs))

    def as_json(fn: Callable[..., Any], *args: Any) -> Callable[[], Any]:
        return lambda: fn(*args, as_json=True)

    return {
        "live": call(client.is_server_live),
        "ready": call(client.is_server_ready),
        "model_ready": call(lambda: client.is_model_ready("particle")),
        "model_ready_v1": call(lambda: client.is_model_ready("particle", "1")),
        "model_ready_missing_version": call(
            lambda: client.is_model_ready("particle", MISSING_VERSION)
        ),
        "model_ready_missing_model": call(lambda: client.is_model_ready("nowhere")),
        "server_metadata": call(as_json(client.get_server_metadata)),
        "model_metadata": call(as_json(client.get_model_metadata, "particle")),
        "model_metadata_v1": call(as_json(client.get_model_metadata, "particle", "1")),
        "model_metadata_missing_version": call(
            as_json(client.get_model_metadata, "particle", MISSING_VERSION)
        ),
        "model_metadata_missing_model": call(as_json(client.get_model_metadata, "nowhere")),
        "model_config": call(as_json(client.get_model_config, "particle")),
        "model_config_missing_version": call(
            as_json(client.get_model_config, "particle", MISSING_VERSION)
        ),
        "repository_index": call(as_json(client.get_model_repository_index)),
        "infer": call(infer(parameters=params)),
        "infer_v1": call(infer(parameters=params, model_version="1")),
        "infer_one_output": call(
            infer(outputs=[triton_grpc.InferRequestedOutput("probabilities")], parameters=params)
        ),
        "infer_missing_version": call(infer(parameters=params, model_version=MISSING_VERSION)),
        "infer_missing_model": call(infer(model="nowhere")),
        "infer_bad_goal": call(infer(inputs=inputs(triton_grpc, observation, goal="zz"))),
        "infer_bad_observation": call(infer(inputs=inputs(triton_grpc, observation[:-1]))),
        "infer_bad_parameter": call(infer(parameters={"seed": "x"})),
        "statistics": call(as_json(client.get_inference_statistics)),
        "model_statistics": call(as_json(client.get_inference_statistics, "particle")),
        "statistics_missing_version": call(
            as_json(client.get_inference_statistics, "particle", MISSING_VERSION)
        ),
        "load_model": call(lambda: client.load_model("particle")),
        "unload_model": call(lambda: client.unload_model("particle")),
        "trace_settings": call(client.get_trace_settings),
        "log_settings": call(client.get_log_settings),
        "system_shared_memory": call(client.get_system_shared_memory_status),
        "cuda_shared_memory": call(client.get_cuda_shared_memory_status),
    }


async def acall(fn: Callable[[], Any]) -> dict[str, Any]:
    try:
        value = await fn()
    except InferenceServerException as err:
        return {"error": err.status(), "message": str(err)}
    except Exception as err:
        return {"crash": f"{type(err).__name__}: {err}"}
    return {"ok": value}


async def aio_calls(module: Any, target: str, observation: list[float]) -> dict[str, Any]:
    """The asyncio clients (`tritonclient.http.aio`, `tritonclient.grpc.aio`), defaults again."""
    client = module.InferenceServerClient(target)
    kwargs = {"as_json": True} if module is triton_grpc_aio else {}
    sync_module = triton_grpc if module is triton_grpc_aio else triton_http

    async def infer(model: str = "particle", version: str = "", goal: str = "a2") -> Any:
        result = await client.infer(
            model,
            inputs(sync_module, observation, goal=goal),
            model_version=version,
            parameters={"seed": 7},
        )
        return outputs_of(result)

    answers = {
        "live": await acall(client.is_server_live),
        "model_ready": await acall(lambda: client.is_model_ready("particle")),
        "model_metadata": await acall(lambda: client.get_model_metadata("particle", **kwargs)),
        "model_config": await acall(lambda: client.get_model_config("particle", **kwargs)),
        "repository_index": await acall(lambda: client.get_model_repository_index(**kwargs)),
        "statistics": await acall(lambda: client.get_inference_statistics(**kwargs)),
        "infer": await acall(infer),
        "infer_missing_version": await acall(lambda: infer(version=MISSING_VERSION)),
        "infer_missing_model": await acall(lambda: infer(model="nowhere")),
        "infer_bad_goal": await acall(lambda: infer(goal="zz")),
        "load_model": await acall(lambda: client.load_model("particle")),
    }
    await client.close()
    return answers


if __name__ == "__main__":
    observation = json.loads(sys.argv[3])
    answers = {
        "http": http_calls(sys.argv[1], observation),
        "grpc": grpc_calls(sys.argv[2], observation),
        "http_aio": asyncio.run(aio_calls(triton_http_aio, sys.argv[1], observation)),
        "grpc_aio": asyncio.run(aio_calls(triton_grpc_aio, sys.argv[2], observation)),
    }
    print(json.dumps(answers, default=str))
