"""The v2 protocol's gRPC service (`inference.GRPCInferenceService`, proto/inference/), beside
`coexist.v1.PolicyService` on the same server (`services.grpc_api.server`), with Triton's
model configuration, statistics and repository index methods.

Inputs may come as typed `contents` or as `raw_input_contents` (little-endian; BYTES elements
each after a 4-byte length), as tritonclient sends them; outputs go back as
`raw_output_contents` (little-endian, one entry per output answered, in order), which is how
Triton answers and what its client reads; `outputs` names the ones wanted (default: all). Errors:
`services.grpc_api.errors` (INVALID_ARGUMENT naming the input or parameter, NOT_FOUND for an
unknown model or version, UNAVAILABLE when the store is down). Methods not listed here (load,
unload, shared memory, trace, log settings) are UNIMPLEMENTED.
"""

from __future__ import annotations

from typing import Any

import grpc

from services.engine import InferenceEngine, InvalidRequest
from services.grpc_api.errors import parse_or_malformed, translate_errors
from services.grpc_api.gen.inference import grpc_predict_v2_pb2 as pb
from services.oip import core
from services.version import VERSION

SERVICE_NAME = "inference.GRPCInferenceService"
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


def _tensor(item: Any, raw: bytes | None) -> core.Tensor:
    datatype, name = item.datatype, item.name
    if raw is not None:
        data: Any = core.decode_raw(name, datatype, raw)
    else:
        if datatype not in _CONTENTS:
            raise InvalidRequest(f"inputs[{name}]", f"unsupported datatype {datatype!r}")
        values = getattr(item.contents, _CONTENTS[datatype])
        data = [v.decode("utf-8", "replace") for v in values] if datatype == "BYTES" else values
    return core.Tensor(name, datatype, tuple(item.shape), data)


def _stats(entry: dict[str, Any]) -> pb.ModelStatistics:
    durations = {k: pb.StatisticDuration(**v) for k, v in entry["inference_stats"].items()}
    return pb.ModelStatistics(
        name=entry["name"],
        version=entry["version"],
        last_inference=entry["last_inference"],
        inference_count=entry["inference_count"],
        execution_count=entry["execution_count"],
        inference_stats=pb.InferStatistics(**durations),
    )


class InferenceServicer:
    """The v2 service over the engine; see the module docstring."""

    def __init__(self, engine: InferenceEngine) -> None:
        self.engine = engine

    def _ready(self) -> bool:
        status = self.engine.status()
        return bool(status.store_reachable and status.models_loaded > 0)

    @translate_errors
    def ServerLive(self, request: Any, context: grpc.ServicerContext) -> pb.ServerLiveResponse:
        return pb.ServerLiveResponse(live=True)

    @translate_errors
    def ServerReady(self, request: Any, context: grpc.ServicerContext) -> pb.ServerReadyResponse:
        return pb.ServerReadyResponse(ready=self._ready())

    @translate_errors
    def ModelReady(
        self, request: pb.ModelReadyRequest, context: grpc.ServicerContext
    ) -> pb.ModelReadyResponse:
        core.check_model(request.name, request.version)
        ready, _reason = core.model_state(self.engine, request.name)
        return pb.ModelReadyResponse(ready=ready)

    @translate_errors
    def ServerMetadata(
        self, request: Any, context: grpc.ServicerContext
    ) -> pb.ServerMetadataResponse:
        return pb.ServerMetadataResponse(
            name="coexist", version=VERSION, extensions=list(core.EXTENSIONS)
        )

    @translate_errors
    def ModelMetadata(
        self, request: pb.ModelMetadataRequest, context: grpc.ServicerContext
    ) -> pb.ModelMetadataResponse:
        meta = core.model_metadata(request.name, request.version)
        return pb.ModelMetadataResponse(
            name=meta["name"],
            versions=meta["versions"],
            platform=meta["platform"],
            inputs=[pb.ModelMetadataResponse.TensorMetadata(**t) for t in meta["inputs"]],
            outputs=[pb.ModelMetadataResponse.TensorMetadata(**t) for t in meta["outputs"]],
        )

    @translate_errors
    def ModelConfig(
        self, request: pb.ModelConfigRequest, context: grpc.ServicerContext
    ) -> pb.ModelConfigResponse:
        config = core.model_config(request.name, request.version, max_batch=self.engine.max_batch)
        policy = pb.ModelVersionPolicy(
            specific=pb.ModelVersionPolicy.Specific(
                versions=config["version_policy"]["specific"]["versions"]
            )
        )

        def tensor(kind: Any, item: dict[str, Any]) -> Any:
            return kind(
                name=item["name"], data_type=pb.DataType.Value(item["data_type"]), dims=item["dims"]
            )

        return pb.ModelConfigResponse(
            config=pb.ModelConfig(
                name=config["name"],
                platform=config["platform"],
                backend=config["backend"],
                version_policy=policy,
                max_batch_size=config["max_batch_size"],
                input=[tensor(pb.ModelInput, t) for t in config["input"]],
                output=[tensor(pb.ModelOutput, t) for t in config["output"]],
                parameters={
                    key: pb.ModelParameter(string_value=value["string_value"])
                    for key, value in config["parameters"].items()
                },
            )
        )

    @translate_errors
    def ModelStatistics(
        self, request: pb.ModelStatisticsRequest, context: grpc.ServicerContext
    ) -> pb.ModelStatisticsResponse:
        entries = core.STATISTICS.model_stats(request.name or None, request.version)
        return pb.ModelStatisticsResponse(model_stats=[_stats(e) for e in entries])

    @translate_errors
    def RepositoryIndex(
        self, request: pb.RepositoryIndexRequest, context: grpc.ServicerContext
    ) -> pb.RepositoryIndexResponse:
        if request.repository_name not in ("", "coexist"):
            raise InvalidRequest(
                "repository_name", "coexist has one repository (its registry): leave it empty"
            )
        index = core.repository_index(self.engine, request.ready)
        return pb.RepositoryIndexResponse(
            models=[pb.RepositoryIndexResponse.ModelIndex(**model) for model in index]
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
        requested = [
            (o.name, {k: _parameter(v) for k, v in o.parameters.items()}) for o in request.outputs
        ]
        inference = core.inference(
            request.model_name, request.model_version, tensors, parameters, requested
        )
        results = core.infer(self.engine, inference.act, core.STATISTICS)
        response = pb.ModelInferResponse(
            model_name=request.model_name, model_version=core.MODEL_VERSION, id=request.id
        )
        names = [name for name, _binary in inference.outputs]  # gRPC: always raw contents
        for name, datatype, shape, data in core.outputs(results, names):
            response.outputs.add(name=name, datatype=datatype, shape=shape)
            response.raw_output_contents.append(core.encode_raw(datatype, data))
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
        "ModelConfig": (pb.ModelConfigRequest, pb.ModelConfigResponse),
        "ModelStatistics": (pb.ModelStatisticsRequest, pb.ModelStatisticsResponse),
        "RepositoryIndex": (pb.RepositoryIndexRequest, pb.RepositoryIndexResponse),
    }
    return {
        name: grpc.unary_unary_rpc_method_handler(
            getattr(servicer, name),
            request_deserializer=parse_or_malformed(request),
            response_serializer=response.SerializeToString,
        )
        for name, (request, response) in messages.items()
    }
