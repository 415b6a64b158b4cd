"""The v2 protocol's gRPC service (`inference.GRPCInferenceService`, proto/inference/), beside
`coexist.v1.PolicyService` on the same server (`services.grpc_api.server`).

Inputs may come as typed `contents` or as `raw_input_contents` (little-endian; BYTES elements
each after a 4-byte length), as tritonclient sends them; outputs go back as
`raw_output_contents` (little-endian, one entry per output, in order), which is how Triton answers
and what its client reads. Errors:
`services.grpc_api.errors` (INVALID_ARGUMENT naming the input or parameter).
"""

from __future__ import annotations

import struct
from typing import Any

import grpc
import numpy as np

from services.engine import InferenceEngine, InvalidRequest
from services.grpc_api.errors import translate_errors
from services.grpc_api.gen.inference import grpc_predict_v2_pb2 as pb
from services.oip import core
from services.version import VERSION

SERVICE_NAME = "inference.GRPCInferenceService"
_NUMPY = {"FP32": "<f4", "FP64": "<f8", "INT32": "<i4", "INT64": "<i8"}
_CONTENTS = {
    "FP32": "fp32_contents",
    "FP64": "fp64_contents",
    "INT32": "int_contents",
    "INT64": "int64_contents",
    "BYTES": "bytes_contents",
}


def _parameter(value: pb.InferParameter) -> Any:
    kind = value.WhichOneof("parameter_choice")
    return None if kind is None else getattr(value, kind)


def _raw_strings(raw: bytes, name: str) -> list[str]:
    out, offset = [], 0
    while offset < len(raw):
        if offset + 4 > len(raw):
            raise InvalidRequest(f"inputs[{name}]", "BYTES raw contents cut short")
        (size,) = struct.unpack_from("<I", raw, offset)
        out.append(raw[offset + 4 : offset + 4 + size].decode("utf-8", "replace"))
        offset += 4 + size
    return out


def _tensor(item: Any, raw: bytes | None) -> core.Tensor:
    datatype, name = item.datatype, item.name
    if raw is not None:
        if datatype == "BYTES":
            data: Any = _raw_strings(raw, name)
        elif datatype in _NUMPY:
            width = np.dtype(_NUMPY[datatype]).itemsize
            if len(raw) % width:
                raise InvalidRequest(f"inputs[{name}]", f"raw contents are not {datatype}")
            data = np.frombuffer(raw, dtype=_NUMPY[datatype])
        else:
            raise InvalidRequest(f"inputs[{name}]", f"unsupported datatype {datatype}")
    else:
        values = getattr(item.contents, _CONTENTS.get(datatype, "fp64_contents"))
        data = [v.decode("utf-8", "replace") for v in values] if datatype == "BYTES" else values
    return core.Tensor(name, datatype, tuple(item.shape), data)


class InferenceServicer:
    """The v2 service over the engine; see the module docstring."""

    def __init__(self, engine: InferenceEngine) -> None:
        self.engine = engine

    def _ready(self) -> bool:
        status = self.engine.status()
        return bool(status.store_reachable and status.models_loaded > 0)

    def ServerLive(self, request: Any, context: grpc.ServicerContext) -> pb.ServerLiveResponse:
        return pb.ServerLiveResponse(live=True)

    def ServerReady(self, request: Any, context: grpc.ServicerContext) -> pb.ServerReadyResponse:
        return pb.ServerReadyResponse(ready=self._ready())

    def ModelReady(
        self, request: pb.ModelReadyRequest, context: grpc.ServicerContext
    ) -> pb.ModelReadyResponse:
        return pb.ModelReadyResponse(ready=core.model_ready(self.engine, request.name))

    def ServerMetadata(
        self, request: Any, context: grpc.ServicerContext
    ) -> pb.ServerMetadataResponse:
        return pb.ServerMetadataResponse(name="coexist", version=VERSION)

    @translate_errors
    def ModelMetadata(
        self, request: pb.ModelMetadataRequest, context: grpc.ServicerContext
    ) -> pb.ModelMetadataResponse:
        meta = core.model_metadata(request.name)
        return pb.ModelMetadataResponse(
            name=meta["name"],
            versions=meta["versions"],
            platform=meta["platform"],
            inputs=[pb.ModelMetadataResponse.TensorMetadata(**t) for t in meta["inputs"]],
            outputs=[pb.ModelMetadataResponse.TensorMetadata(**t) for t in meta["outputs"]],
        )

    @translate_errors
    def ModelInfer(
        self, request: pb.ModelInferRequest, context: grpc.ServicerContext
    ) -> pb.ModelInferResponse:
        raw = list(request.raw_input_contents)
        if raw and len(raw) != len(request.inputs):
            raise InvalidRequest("raw_input_contents", "expected one entry per input")
        tensors = [_tensor(item, raw[k] if raw else None) for k, item in enumerate(request.inputs)]
        parameters = {k: _parameter(v) for k, v in request.parameters.items()}
        act = core.act_request(request.model_name, tensors, parameters)
        response = pb.ModelInferResponse(
            model_name=request.model_name, model_version=core.MODEL_VERSION, id=request.id
        )
        for name, datatype, shape, data in core.outputs(core.infer(self.engine, act)):
            response.outputs.add(name=name, datatype=datatype, shape=shape)
            response.raw_output_contents.append(data.astype(_NUMPY[datatype]).tobytes())
        return response


def handlers(servicer: InferenceServicer) -> dict[str, grpc.RpcMethodHandler]:
    """The service's method handlers, for `grpc.method_handlers_generic_handler`."""
    messages: dict[str, tuple[Any, Any]] = {
        "ServerLive": (pb.ServerLiveRequest, pb.ServerLiveResponse),
        "ServerReady": (pb.ServerReadyRequest, pb.ServerReadyResponse),
        "ModelReady": (pb.ModelReadyRequest, pb.ModelReadyResponse),
        "ServerMetadata": (pb.ServerMetadataRequest, pb.ServerMetadataResponse),
        "ModelMetadata": (pb.ModelMetadataRequest, pb.ModelMetadataResponse),
        "ModelInfer": (pb.ModelInferRequest, pb.ModelInferResponse),
    }
    return {
        name: grpc.unary_unary_rpc_method_handler(
            getattr(servicer, name),
            request_deserializer=request.FromString,
            response_serializer=response.SerializeToString,
        )
        for name, (request, response) in messages.items()
    }
