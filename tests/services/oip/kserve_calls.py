"""Run as a script by test_open_inference.py with a Python that has KServe's package (`kserve`,
not in the dev extra: docs/client.md says why): KServe's own v2 clients and types
(`InferenceRESTClient`, `InferenceGRPCClient`, `InferRequest`, `InferInput`) against a coexist
server, printing what each call answered as one JSON object.

    KSERVE_PYTHON=/path/to/python-with-kserve pytest tests/services/oip -k kserve
    python kserve_calls.py http://HOST:PORT GRPC_HOST:PORT OBSERVATION_JSON

A call is `{"ok": value}`, `{"error": "<status>", "message": ...}` for the clients' documented
errors (REST: `httpx.HTTPStatusError`; gRPC: `grpc.RpcError`), or `{"crash": ...}` for any
other exception.
"""

from __future__ import annotations

import asyncio
import json
import sys
from collections.abc import Awaitable, Callable
from typing import Any

import grpc
import httpx
import numpy as np
from kserve import InferenceGRPCClient, InferenceRESTClient, InferInput, InferRequest
from kserve.inference_client import RESTConfig

OUTPUTS = ("probabilities", "action", "greedy_action")


async def call(make: Callable[[], Awaitable[Any]]) -> dict[str, Any]:
    try:
        value = await make()
    except httpx.HTTPStatusError as err:
        return {"error": str(err.response.status_code), "message": str(err)}
    except grpc.RpcError as err:
        return {"error": str(err.code()), "message": str(err.details())}
    except Exception as err:  # what the test forbids
        return {"crash": f"{type(err).__name__}: {err}"}
    return {"ok": value}


def request(
    observation: list[float], binary: bool, goal: str = "a2", version: str | None = None
) -> InferRequest:
    obs = InferInput("observation", [1, len(observation)], "FP32")
    obs.set_data_from_numpy(np.asarray([observation], dtype=np.float32), binary_data=binary)
    ego = InferInput("ego_goal", [1], "BYTES")
    ego.set_data_from_numpy(np.asarray([goal.encode()], dtype=np.object_), binary_data=binary)
    partners = InferInput("partner_goals", [1], "BYTES")
    partners.set_data_from_numpy(np.asarray([b"b3"], dtype=np.object_), binary_data=binary)
    return InferRequest(
        "particle", [obs, ego, partners], parameters={"seed": 7}, model_version=version
    )


def outputs_of(response: Any) -> dict[str, Any]:
    return {o.name: o.as_numpy().tolist() for o in response.outputs if o.name in OUTPUTS}


async def main(http_url: str, grpc_target: str, observation: list[float]) -> dict[str, Any]:
    rest = InferenceRESTClient(RESTConfig(protocol="v2"))
    answers: dict[str, Any] = {
        "rest": {
            "live": await call(lambda: rest.is_server_live(http_url)),
            "ready": await call(lambda: rest.is_server_ready(http_url)),
            "model_ready": await call(lambda: rest.is_model_ready(http_url, "particle")),
            "model_ready_missing_model": await call(lambda: rest.is_model_ready(http_url, "no")),
            "infer_json": await call(
                lambda: _infer_rest(rest, http_url, request(observation, binary=False))
            ),
            "infer_binary": await call(
                lambda: _infer_rest(rest, http_url, request(observation, binary=True))
            ),
            "infer_bad_goal": await call(
                lambda: _infer_rest(rest, http_url, request(observation, False, goal="zz"))
            ),
            "infer_missing_model": await call(
                lambda: _infer_rest(rest, http_url, request(observation, False), model="no")
            ),
        }
    }
    await rest.close()
    client = InferenceGRPCClient(grpc_target)
    answers["grpc"] = {
        "live": await call(client.is_server_live),
        "ready": await call(client.is_server_ready),
        "model_ready": await call(lambda: client.is_model_ready("particle")),
        "infer": await call(lambda: _infer_grpc(client, request(observation, binary=True))),
        "infer_v1": await call(
            lambda: _infer_grpc(client, request(observation, binary=True, version="1"))
        ),
        "infer_missing_version": await call(
            lambda: _infer_grpc(client, request(observation, True, version="999999999999"))
        ),
        "infer_bad_goal": await call(
            lambda: _infer_grpc(client, request(observation, True, goal="zz"))
        ),
    }
    await client.close()
    return answers


async def _infer_rest(
    client: InferenceRESTClient, url: str, infer_request: InferRequest, model: str = "particle"
) -> dict[str, Any]:
    return outputs_of(await client.infer(url, infer_request, model_name=model))


async def _infer_grpc(client: InferenceGRPCClient, infer_request: InferRequest) -> dict[str, Any]:
    return outputs_of(await client.infer(infer_request))


if __name__ == "__main__":
    found = asyncio.run(main(sys.argv[1], sys.argv[2], json.loads(sys.argv[3])))
    print(json.dumps(found, default=str))
