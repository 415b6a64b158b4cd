"""The v2 protocol's REST endpoints (`services.oip`): JSON tensors in, JSON tensors out.

Tensor data is JSON (the protocol's binary-data extension is not served: ask tritonclient for
`binary_data=False`). Errors have the `/v1` shape (`{"error": {"code", "message", "field"}}`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from fastapi import APIRouter, Request, Response
from fastapi.responses import JSONResponse
from starlette.concurrency import run_in_threadpool

from services.engine import InferenceEngine, InvalidRequest
from services.oip import core
from services.rest.json_body import FastJsonRoute
from services.version import VERSION

router = APIRouter(prefix="/v2", tags=["open inference protocol (v2)"], route_class=FastJsonRoute)


def _engine(request: Request) -> InferenceEngine:
    engine: InferenceEngine = request.app.state.engine
    return engine


@router.get("/health/live")
async def live() -> dict[str, bool]:
    return {"live": True}


@router.get("/health/ready")
async def ready(request: Request) -> JSONResponse:
    status = _engine(request).status()
    ok = bool(status.store_reachable and status.models_loaded > 0)
    return JSONResponse({"ready": ok}, status_code=200 if ok else 503)


@router.get("")
async def server_metadata() -> dict[str, Any]:
    return {"name": "coexist", "version": VERSION, "extensions": []}


@router.get("/models/{env}")
@router.get("/models/{env}/versions/{version}")
async def model_metadata(env: str, version: str = core.MODEL_VERSION) -> dict[str, Any]:
    return core.model_metadata(env)


@router.get("/models/{env}/ready")
@router.get("/models/{env}/versions/{version}/ready")
async def model_ready(request: Request, env: str, version: str = core.MODEL_VERSION) -> Response:
    ok = core.model_ready(_engine(request), env)
    return JSONResponse({"name": env, "ready": ok}, status_code=200 if ok else 400)


def _tensor(item: Any, k: int) -> core.Tensor:
    if not isinstance(item, dict):
        raise InvalidRequest(f"inputs[{k}]", "expected an object (name, datatype, shape, data)")
    name = str(item.get("name", k))
    shape, data = item.get("shape"), item.get("data")
    if not isinstance(shape, list) or not all(isinstance(d, int) for d in shape):
        raise InvalidRequest(f"inputs[{name}].shape", "expected a list of integers")
    if not isinstance(data, list):
        raise InvalidRequest(f"inputs[{name}].data", "expected a list (JSON tensor data)")
    flat = np.asarray(data, dtype=object).ravel().tolist()
    datatype = str(item.get("datatype", ""))
    if datatype != "BYTES" and not all(
        isinstance(x, (int, float)) and not isinstance(x, bool) for x in flat
    ):
        raise InvalidRequest(f"inputs[{name}].data", "expected numbers")
    return core.Tensor(name, datatype, tuple(shape), flat)


@router.post("/models/{env}/infer")
@router.post("/models/{env}/versions/{version}/infer")
async def infer(request: Request, env: str, version: str = core.MODEL_VERSION) -> dict[str, Any]:
    """One v2 inference: an act for one or more observations (`services.oip.core`)."""
    try:
        body = await request.json()
    except ValueError:
        raise InvalidRequest("body", "expected a JSON object") from None
    if not isinstance(body, dict) or not isinstance(body.get("inputs"), list):
        raise InvalidRequest("inputs", "expected a list of input tensors")
    parameters = body.get("parameters") or {}
    if not isinstance(parameters, dict):
        raise InvalidRequest("parameters", "expected an object")
    tensors = [_tensor(item, k) for k, item in enumerate(body["inputs"])]
    act = core.act_request(env, tensors, parameters)
    results = await run_in_threadpool(core.infer, _engine(request), act)
    answer: dict[str, Any] = {
        "model_name": env,
        "model_version": core.MODEL_VERSION,
        "outputs": [
            {"name": n, "datatype": t, "shape": s, "data": d.tolist()}
            for n, t, s, d in core.outputs(results)
        ],
    }
    if "id" in body:
        answer["id"] = str(body["id"])
    return answer
