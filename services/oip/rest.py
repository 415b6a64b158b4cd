"""The v2 protocol's REST endpoints (`services.oip`), with Triton's extensions where coexist has
the facts.

| route                                                   | answer                                |
|---------------------------------------------------------|---------------------------------------|
| `GET /v2/health/live`, `/v2/health/ready`               | `{"live"}`, `{"ready"}` (503 if not)  |
| `GET /v2`                                               | server metadata, with the extensions  |
| `GET /v2/models/{m}[/versions/{v}]`                     | model metadata                        |
| `GET /v2/models/{m}[/versions/{v}]/ready`               | 200 ready, 400 not ready              |
| `GET /v2/models/{m}[/versions/{v}]/config`              | Triton's model configuration          |
| `GET /v2/models[/{m}[/versions/{v}]]/stats`             | Triton's statistics (this process)    |
| `POST /v2/models/{m}[/versions/{v}]/infer`              | one inference (JSON or binary data)   |
| `POST /v2/repository/index`                             | Triton's repository index             |
| `POST /v2/repository/models/{m}/load`, `/unload`        | 400: networks load from the registry on demand |

Tensor data is JSON, or binary (the binary tensor data extension): a body whose
`Inference-Header-Content-Length` header says how long its JSON part is, the inputs whose
parameter `binary_data_size` is set following it in input order; outputs are binary when the
request's `binary_data_output` or the output's `binary_data` asks, and the answer then carries
the same header.

Every error is the protocol's `{"error": "<message>"}` (the message names the field, as on
`/v1`): 400 for a bad request, 404 for an unknown model or version (or route), 503 when the
store is down. `V2ErrorBodies` gives the same shape to the answers made before or beside these
routes (the token gate's 401, the body limit's 413, an unknown route's 404, a 500).
"""

from __future__ import annotations

import functools
from collections.abc import Awaitable, Callable
from typing import Any

import numpy as np
import orjson
from fastapi import APIRouter, Request, Response
from fastapi.responses import JSONResponse
from starlette.concurrency import run_in_threadpool

from model_store.errors import ModelStoreError, clip
from services.engine import EngineError, InferenceEngine, InvalidRequest, ModelNotFound
from services.engine.errors import ModelUnavailable
from services.oip import core
from services.version import VERSION

router = APIRouter(prefix="/v2", tags=["open inference protocol (v2)"])

HEADER_LENGTH = "inference-header-content-length"
OFFLOAD_BYTES = 1 << 20  # bodies from this size on are decoded in a worker thread


def _engine(request: Request) -> InferenceEngine:
    engine: InferenceEngine = request.app.state.engine
    return engine


def error_status(err: Exception) -> int:
    """The v2 status of an error raised while serving a v2 request."""
    if isinstance(err, ModelNotFound):
        return 404
    if isinstance(err, ModelUnavailable | ModelStoreError):
        return 503
    return 400  # InvalidRequest, and the engine's other refusals of a request


def v2_error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": clip(message)}, status_code=status)


def _v2_errors(
    endpoint: Callable[..., Awaitable[Any]],
) -> Callable[..., Awaitable[Any]]:
    """Answer the engine's and the store's errors in the protocol's shape."""

    @functools.wraps(endpoint)
    async def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return await endpoint(*args, **kwargs)
        except (EngineError, ModelStoreError) as err:
            return v2_error(error_status(err), str(err))

    return wrapper


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
    return {"name": "coexist", "version": VERSION, "extensions": list(core.EXTENSIONS)}


# Before `/models/{env}`, which would take "stats" for a model's name.
@router.get("/models/stats")
@_v2_errors
async def all_statistics() -> dict[str, Any]:
    return {"model_stats": core.STATISTICS.model_stats()}


@router.get("/models/{env}")
@router.get("/models/{env}/versions/{version}")
@_v2_errors
async def model_metadata(env: str, version: str | None = None) -> dict[str, Any]:
    return core.model_metadata(env, version)


@router.get("/models/{env}/ready")
@router.get("/models/{env}/versions/{version}/ready")
@_v2_errors
async def model_ready(request: Request, env: str, version: str | None = None) -> Response:
    core.check_model(env, version)
    ok, reason = await run_in_threadpool(core.model_state, _engine(request), env)
    if ok:
        return JSONResponse({"name": env, "ready": True})
    return JSONResponse({"name": env, "ready": False, "error": reason}, status_code=400)


@router.get("/models/{env}/config")
@router.get("/models/{env}/versions/{version}/config")
@_v2_errors
async def model_config(request: Request, env: str, version: str | None = None) -> Any:
    return core.model_config(env, version, max_batch=_engine(request).max_batch)


@router.get("/models/{env}/stats")
@router.get("/models/{env}/versions/{version}/stats")
@_v2_errors
async def model_statistics(env: str, version: str | None = None) -> dict[str, Any]:
    return {"model_stats": core.STATISTICS.model_stats(env, version)}


@router.post("/repository/index")
@_v2_errors
async def repository_index(request: Request) -> Any:
    body = await request.body()
    ready_only = False
    if body.strip():
        try:
            options = orjson.loads(body)
        except orjson.JSONDecodeError:
            raise InvalidRequest("body", "expected a JSON object") from None
        if not isinstance(options, dict):
            raise InvalidRequest("body", "expected a JSON object")
        ready_only = options.get("ready", False)
        if not isinstance(ready_only, bool):
            raise InvalidRequest("ready", "expected true or false")
    return await run_in_threadpool(core.repository_index, _engine(request), ready_only)


@router.post("/repository/models/{env}/load")
@router.post("/repository/models/{env}/unload")
@_v2_errors
async def load_or_unload(env: str) -> Response:
    core.check_model(env)
    return v2_error(
        400,
        f"model {env}: coexist loads each network from its registry when a request needs it; "
        "to change what is served, move an alias (PUT /v1/registry/models/{name}/-/aliases/{alias})",
    )


def _numbers(flat: list[Any], where: str) -> list[Any]:
    if not all(isinstance(x, int | float) and not isinstance(x, bool) for x in flat):
        raise InvalidRequest(where, "expected numbers")
    return flat


def _tensor(item: Any, k: int, binary: bytes, offset: int) -> tuple[core.Tensor, int]:
    """Input `k` of the JSON header, its data from `binary` at `offset` if it says so; and the
    offset of the next input's binary data."""
    if not isinstance(item, dict):
        raise InvalidRequest(f"inputs[{k}]", "expected an object (name, datatype, shape, data)")
    name = str(item.get("name", k))
    shape = item.get("shape")
    if not isinstance(shape, list) or not all(
        isinstance(d, int) and not isinstance(d, bool) for d in shape
    ):
        raise InvalidRequest(f"inputs[{name}].shape", "expected a list of integers")
    datatype = str(item.get("datatype", ""))
    parameters = item.get("parameters") or {}
    if not isinstance(parameters, dict):
        raise InvalidRequest(f"inputs[{name}].parameters", "expected an object")
    size = parameters.get("binary_data_size")
    if size is not None:
        if isinstance(size, bool) or not isinstance(size, int) or size < 0:
            raise InvalidRequest(
                f"inputs[{name}].parameters.binary_data_size", "expected a byte count"
            )
        if offset + size > len(binary):
            raise InvalidRequest(
                f"inputs[{name}].parameters.binary_data_size",
                f"{size} bytes from byte {offset} of the binary data, which has {len(binary)}",
            )
        data = core.decode_raw(name, datatype, binary[offset : offset + size])
        return core.Tensor(name, datatype, tuple(shape), data), offset + size
    data = item.get("data")
    if not isinstance(data, list):
        raise InvalidRequest(f"inputs[{name}].data", "expected a list (JSON tensor data)")
    flat = np.asarray(data, dtype=object).ravel().tolist()
    if datatype != "BYTES":
        flat = _numbers(flat, f"inputs[{name}].data")
    return core.Tensor(name, datatype, tuple(shape), flat), offset


def _outputs(body: dict[str, Any]) -> list[tuple[str, dict[str, Any]]] | None:
    requested = body.get("outputs")
    if requested is None:
        return None
    if not isinstance(requested, list):
        raise InvalidRequest("outputs", "expected a list of {name, parameters}")
    items = []
    for k, item in enumerate(requested):
        if not isinstance(item, dict) or not isinstance(item.get("name"), str):
            raise InvalidRequest(f"outputs[{k}]", "expected an object with a name")
        parameters = item.get("parameters") or {}
        if not isinstance(parameters, dict):
            raise InvalidRequest(f"outputs[{item['name']}].parameters", "expected an object")
        items.append((item["name"], parameters))
    return items


def decode(
    raw: bytes, header_length: str | None, env: str, version: str | None
) -> tuple[core.Inference, Any]:
    """(the inference, the request id or None) of a v2 REST body (module docstring)."""
    json_part, binary = raw, b""
    if header_length is not None:
        try:
            length = int(header_length)
        except ValueError:
            length = -1
        if not 0 <= length <= len(raw):
            raise InvalidRequest(
                "Inference-Header-Content-Length",
                f"expected the JSON part's length in bytes (0 to {len(raw)})",
            )
        json_part, binary = raw[:length], raw[length:]
    try:
        body = orjson.loads(json_part)
    except orjson.JSONDecodeError as err:
        raise InvalidRequest("body", f"expected a JSON object ({err})") from None
    if not isinstance(body, dict) or not isinstance(body.get("inputs"), list):
        raise InvalidRequest("inputs", "expected a list of input tensors")
    parameters = body.get("parameters") or {}
    if not isinstance(parameters, dict):
        raise InvalidRequest("parameters", "expected an object")
    tensors, offset = [], 0
    for k, item in enumerate(body["inputs"]):
        tensor, offset = _tensor(item, k, binary, offset)
        tensors.append(tensor)
    if offset != len(binary):
        raise InvalidRequest(
            "body", f"{len(binary) - offset} bytes of binary data that no input's size claims"
        )
    request_id = body.get("id")
    if request_id is not None and not isinstance(request_id, str | int):
        raise InvalidRequest("id", "expected a string")
    inference = core.inference(env, version, tensors, parameters, _outputs(body))
    return inference, request_id


def encode(env: str, request_id: Any, inference: core.Inference, results: list[Any]) -> Response:
    """The answer: JSON, or JSON then binary data when any output is binary."""
    names = [name for name, _ in inference.outputs]
    binary_of = dict(inference.outputs)
    answer: dict[str, Any] = {"model_name": env, "model_version": core.MODEL_VERSION}
    if request_id is not None:
        answer["id"] = str(request_id)
    items, chunks = [], []
    for name, datatype, shape, data in core.outputs(results, names):
        item: dict[str, Any] = {"name": name, "datatype": datatype, "shape": shape}
        if binary_of[name]:
            chunk = core.encode_raw(datatype, data)
            item["parameters"] = {"binary_data_size": len(chunk)}
            chunks.append(chunk)
        else:
            item["data"] = data.tolist()
        items.append(item)
    answer["outputs"] = items
    header = orjson.dumps(answer)
    if not chunks:
        return Response(header, media_type="application/json")
    return Response(
        b"".join([header, *chunks]),
        media_type="application/octet-stream",
        headers={"Inference-Header-Content-Length": str(len(header))},
    )


@router.post("/models/{env}/infer")
@router.post("/models/{env}/versions/{version}/infer")
@_v2_errors
async def infer(request: Request, env: str, version: str | None = None) -> Response:
    """One v2 inference: an act for one or more observations (`services.oip.core`)."""
    raw = await request.body()
    header_length = request.headers.get(HEADER_LENGTH)
    if len(raw) >= OFFLOAD_BYTES:
        inference, request_id = await run_in_threadpool(decode, raw, header_length, env, version)
    else:
        inference, request_id = decode(raw, header_length, env, version)
    results = await run_in_threadpool(core.infer, _engine(request), inference.act, core.STATISTICS)
    return encode(env, request_id, inference, results)


Message = dict[str, Any]
MAX_ERROR_BYTES = 1 << 16  # an error body longer than this is passed on as it is


class V2ErrorBodies:
    """Pure ASGI: an error answer to a `/v2` path that is not the protocol's `{"error": str}`
    (the token gate's, the body limit's, FastAPI's 404 and 405, a 500) is rewritten to it, the
    message kept; a 422 becomes the protocol's 400. Other paths and every success pass
    untouched, at the cost of one prefix test."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        path = scope.get("path", "") if scope["type"] == "http" else ""
        if not (path == "/v2" or path.startswith("/v2/")):
            await self.app(scope, receive, send)
            return
        start: Message | None = None
        chunks: list[bytes] = []

        async def rewrite(message: Message) -> None:
            nonlocal start
            if message["type"] == "http.response.start" and message["status"] >= 400:
                start = message  # held until the body is complete
                return
            if start is None or message["type"] != "http.response.body":
                await send(message)
                return
            chunks.append(message.get("body", b""))
            if message.get("more_body", False):
                return
            status, body = _protocol_error(start["status"], b"".join(chunks))
            headers = [
                (k, v)
                for k, v in start.get("headers", [])
                if k.lower() not in (b"content-length", b"content-type")
            ]
            headers += [
                (b"content-length", str(len(body)).encode()),
                (b"content-type", b"application/json"),
            ]
            await send({**start, "status": status, "headers": headers})
            await send({"type": "http.response.body", "body": body})

        await self.app(scope, receive, rewrite)


def _protocol_error(status: int, body: bytes) -> tuple[int, bytes]:
    """(status, body) of an error answer in the protocol's shape (`V2ErrorBodies`)."""
    message: Any = None
    try:
        parsed = orjson.loads(body) if len(body) <= MAX_ERROR_BYTES else None
    except orjson.JSONDecodeError:
        parsed = None
    if isinstance(parsed, dict):
        error = parsed.get("error")
        if isinstance(error, str):
            return status, body  # already the protocol's
        if isinstance(error, dict):  # an older `{"error": {"message": ...}}`
            message = error.get("message")
        # problem details (services.problems), FastAPI's `{"detail": ...}`
        message = message or parsed.get("detail") or parsed.get("title")
    if not isinstance(message, str):
        message = body.decode("utf-8", "replace").strip() if 0 < len(body) <= 2000 else ""
    if status == 404 and message in ("", "Not Found"):
        message = "no such v2 route (see GET /v2 and the model routes)"
    if status == 405 and message in ("", "Method Not Allowed"):
        message = "this v2 route does not take that method"
    status = 400 if status == 422 else status
    return status, orjson.dumps({"error": clip(message or f"HTTP {status}")})
