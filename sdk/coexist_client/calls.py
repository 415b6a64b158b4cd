"""The policy API's exchanges over either transport: one plan per operation, HTTP or gRPC
chosen by the transport (`transport.grpc`).

| plan                         | REST                     | gRPC (`coexist.v1.PolicyService`) |
|------------------------------|--------------------------|-----------------------------------|
| `act_exchange(t, body)`      | `POST /v1/act`           | `Act`                             |
| `columns_exchange(t, body)`  | `POST /v1/act:batch`     | `ActBatch` (`observation_matrix`, `BATCH_FORMAT_COLUMNS`) |
| `envs_exchange(t)`           | `GET /v1/envs`           | `ListEnvs`                        |
| `health_exchange(t)`         | `/healthz`, `/readyz`    | `grpc.health.v1.Health/Check`     |

Bodies are the REST JSON (`coexist_client.bodies`); `coexist_client.proto` translates them.
"""

from __future__ import annotations

from typing import Any

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

from coexist_client import proto
from coexist_client.errors import CoexistError
from coexist_client.exchange import Plan
from coexist_client.gen.coexist.v1 import policy_pb2 as pb
from coexist_client.transport import Http, Unary
from coexist_client.types import Action, ActionColumns, EnvInfo, Health

SERVICE = "/coexist.v1.PolicyService"
SERVICE_NAME = "coexist.v1.PolicyService"


def act_exchange(transport: Any, body: dict[str, Any]) -> Plan[Action]:
    if transport.grpc:
        response = yield Unary(f"{SERVICE}/Act", proto.act_request(body), pb.ActResponse)
        return proto.action_from_proto(response)
    return Action.from_json((yield Http("POST", "/v1/act", body)))


def columns_exchange(transport: Any, body: dict[str, Any]) -> Plan[ActionColumns]:
    body = {**body, "format": "columns"}  # an `act_batch_body`, answered as columns
    if not transport.grpc:
        return ActionColumns.from_json((yield Http("POST", "/v1/act:batch", body)))
    request = proto.act_batch_request(body)
    try:
        response = yield Unary(f"{SERVICE}/ActBatch", request, pb.ActBatchResponse)
    except CoexistError as err:  # the matrix is how the SDK sent `observations`
        raise proto.blame_observations(err) from None
    return proto.columns_from_proto(response.columns)


def envs_exchange(transport: Any) -> Plan[list[EnvInfo]]:
    if transport.grpc:
        response = yield Unary(f"{SERVICE}/ListEnvs", pb.ListEnvsRequest(), pb.ListEnvsResponse)
        return [proto.env_from_proto(e) for e in response.envs]
    data = yield Http("GET", "/v1/envs")
    items = data["envs"] if isinstance(data, dict) else data
    return [EnvInfo.from_json(e) for e in items]


def _health_messages() -> tuple[Any, Any]:
    """The standard health check's two messages, built in a pool of their own (the SDK carries
    no generated code for them, and the default pool may hold grpcio-health-checking's)."""
    file = descriptor_pb2.FileDescriptorProto(
        name="coexist_client/health.proto", package="grpc.health.v1", syntax="proto3"
    )
    string, enum = (
        descriptor_pb2.FieldDescriptorProto.TYPE_STRING,
        descriptor_pb2.FieldDescriptorProto.TYPE_ENUM,
    )
    request = file.message_type.add(name="HealthCheckRequest")
    request.field.add(name="service", number=1, type=string, label=1)
    response = file.message_type.add(name="HealthCheckResponse")
    status = response.enum_type.add(name="ServingStatus")
    for number, name in enumerate(("UNKNOWN", "SERVING", "NOT_SERVING", "SERVICE_UNKNOWN")):
        status.value.add(name=name, number=number)
    response.field.add(
        name="status",
        number=1,
        type=enum,
        label=1,
        type_name=".grpc.health.v1.HealthCheckResponse.ServingStatus",
    )
    pool = descriptor_pool.DescriptorPool()
    pool.Add(file)
    request_class, response_class = (
        message_factory.GetMessageClass(pool.FindMessageTypeByName(f"grpc.health.v1.{name}"))
        for name in ("HealthCheckRequest", "HealthCheckResponse")
    )
    return request_class, response_class


HealthCheckRequest, HealthCheckResponse = _health_messages()


def health_exchange(transport: Any) -> Plan[Health]:
    if transport.grpc:
        request = HealthCheckRequest(service=SERVICE_NAME)
        response = yield Unary("/grpc.health.v1.Health/Check", request, HealthCheckResponse)
        name = HealthCheckResponse.ServingStatus.Name(response.status)
        return Health(live=True, ready=name == "SERVING", detail={"status": name})
    live = yield Http("GET", "/healthz")
    try:  # not ready: 503, an answer in itself (not retried)
        ready, detail = True, (yield Http("GET", "/readyz", retry=False))
    except CoexistError as err:
        ready, detail = False, {"code": err.code, "message": err.message}
    return Health(live=bool(live), ready=ready, detail=detail or {})
