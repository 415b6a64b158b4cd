"""Run as a script by test_open_inference.py: Triton's official client (`tritonclient`, HTTP and
gRPC) against a coexist server, printing what it answered as one JSON object.

    python triton_calls.py HTTP_HOST:PORT GRPC_HOST:PORT OBSERVATION_JSON

It runs in a process of its own because `tritonclient.grpc` and the server's generated v2 code
both define the protocol's messages (package `inference`) in protobuf's default pool, which
refuses a second definition: a real client never shares the server's process anyway.
"""

from __future__ import annotations

import json
import sys
from typing import Any

import numpy as np
import tritonclient.grpc as triton_grpc
import tritonclient.http as triton_http


def _inputs(module: Any, observation: list[float], json_data: bool) -> list[Any]:
    obs = module.InferInput("observation", [1, len(observation)], "FP32")
    goal = module.InferInput("ego_goal", [1], "BYTES")
    partners = module.InferInput("partner_goals", [1], "BYTES")
    kwargs = {"binary_data": False} if json_data else {}
    obs.set_data_from_numpy(np.asarray([observation], dtype=np.float32), **kwargs)
    goal.set_data_from_numpy(np.asarray([b"a2"], dtype=np.object_), **kwargs)
    partners.set_data_from_numpy(np.asarray([b"b3"], dtype=np.object_), **kwargs)
    return [obs, goal, partners]


def main(http_target: str, grpc_target: str, observation: list[float]) -> dict[str, Any]:
    answers: dict[str, Any] = {}
    http = triton_http.InferenceServerClient(http_target)
    outputs = [
        triton_http.InferRequestedOutput(n, binary_data=False)
        for n in ("probabilities", "action", "greedy_action")
    ]
    result = http.infer(
        "particle",
        _inputs(triton_http, observation, True),
        outputs=outputs,
        parameters={"seed": 7, "method": "aail_bounded"},
    )
    answers["http"] = {
        "live": http.is_server_live(),
        "ready": http.is_server_ready(),
        "model_ready": http.is_model_ready("particle"),
        "metadata": http.get_model_metadata("particle"),
        "probabilities": result.as_numpy("probabilities").tolist(),
        "action": result.as_numpy("action").tolist(),
    }
    grpc = triton_grpc.InferenceServerClient(grpc_target)
    result = grpc.infer(
        "particle",
        _inputs(triton_grpc, observation, False),
        parameters={"seed": 7, "method": "aail_bounded"},
    )
    metadata = grpc.get_model_metadata("particle", as_json=True)
    answers["grpc"] = {
        "live": grpc.is_server_live(),
        "ready": grpc.is_server_ready(),
        "model_ready": grpc.is_model_ready("particle"),
        "metadata": metadata,
        "probabilities": result.as_numpy("probabilities").tolist(),
        "action": result.as_numpy("action").tolist(),
    }
    try:
        grpc.infer("particle", _inputs(triton_grpc, observation[:-1], False))
        answers["grpc_bad"] = None
    except triton_grpc.InferenceServerException as err:
        answers["grpc_bad"] = {"status": err.status(), "message": err.message()}
    return answers


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1], sys.argv[2], json.loads(sys.argv[3]))))
