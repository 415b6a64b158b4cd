"""gRPC clients: `GrpcCoexistClient` (sync) and `AsyncGrpcCoexistClient` (grpc.aio).

    with GrpcCoexistClient("127.0.0.1:50051") as client:       # or "grpc://127.0.0.1:50051"
        a = client.act("particle", "a2", obs, partners={1: "b3"}, seed=7)
        with client.episode("particle", "a2", partners={1: "b3"}, seed=0) as ep:
            a = ep.act(obs)                                      # one Episode stream message
        with client.episode("particle", "a2", partners={1: None}) as ep:  # goal inferred
            ep.act(obs_0); a = ep.act(obs_1, observed={1: 3})    # a.beliefs[0].top

The same methods and results as the HTTP clients (`act`, `act_batch`, `act_batch_columns`,
`envs`, `health`, `episode`); one persistent channel per client. A batch travels as one
`observation_matrix` and comes back as `ActColumns` (`act_batch` makes its `Action`s; errors
about the matrix name `observations`, as over HTTP). Errors raise `services.sdk.errors` classes;
the field comes from the server's `coexist-field` trailing metadata. `token=` sends a bearer token
with every call, `tls=True` / `root_certificates=` (or a `grpcs://` target) speak TLS
(`services.sdk.connect`).
"""

from __future__ import annotations

import queue
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import grpc
from grpc_health.v1 import health_pb2, health_pb2_grpc
from numpy.typing import ArrayLike

from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.grpc_api.gen.coexist.v1 import policy_pb2_grpc as pb_grpc
from services.sdk import proto
from services.sdk.bodies import (
    Observed,
    Partners,
    act_batch_body,
    act_body,
    observation_fields,
    observed_entries,
    session_body,
)
from services.sdk.connect import Metadata, grpc_channel, grpc_metadata
from services.sdk.errors import CoexistError, error_for_grpc
from services.sdk.types import Action, ActionColumns, EnvInfo, Health, rows_of

SERVICE_NAME = "coexist.v1.PolicyService"
FIELD_METADATA_KEY = "coexist-field"
DEFAULT_TARGET = "127.0.0.1:50051"


def sdk_error(err: grpc.RpcError) -> CoexistError:
    """The SDK error for a failed call (sync `grpc.RpcError` or `grpc.aio.AioRpcError`)."""
    code = err.code() if hasattr(err, "code") else grpc.StatusCode.UNKNOWN
    details = (err.details() if hasattr(err, "details") else None) or str(code)
    metadata = err.trailing_metadata() if hasattr(err, "trailing_metadata") else None
    field = next((v for k, v in (metadata or ()) if k == FIELD_METADATA_KEY), None)
    return error_for_grpc(code.name, details, field)


class GrpcCoexistClient:
    """Synchronous gRPC client; see the module docstring."""

    def __init__(
        self,
        target: str = DEFAULT_TARGET,
        *,
        timeout: float | None = 10.0,
        options: list[tuple[str, Any]] | None = None,
        token: str | None = None,
        tls: bool = False,
        root_certificates: str | Path | None = None,
    ) -> None:
        self._channel = grpc_channel(
            target, tls=tls, root_certificates=root_certificates, options=options
        )
        self._stub = pb_grpc.PolicyServiceStub(self._channel)
        self._timeout = timeout
        self._metadata = grpc_metadata(token)

    def _call(self, method: Any, request: Any) -> Any:
        try:
            return method(request, timeout=self._timeout, metadata=self._metadata)
        except grpc.RpcError as err:
            raise sdk_error(err) from None

    def act(
        self,
        env: str,
        ego_goal: str,
        observation: ArrayLike | None = None,
        *,
        state: ArrayLike | None = None,
        ego_index: int = 0,
        partners: Partners = None,
        method: str = "aail_bounded",
        temperature: float | None = None,
        regret_bound: float | None = None,
        seed: int | None = None,
        alias: str = "production",
        versions: Mapping[str, int] | None = None,
    ) -> Action:
        body = act_body(
            env, ego_goal, observation, state=state, ego_index=ego_index, partners=partners,
            method=method, temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias, versions=versions,
        )  # fmt: skip
        return proto.action_from_proto(self._call(self._stub.Act, proto.act_request(body)))

    def act_batch_columns(
        self,
        env: str,
        ego_goal: str,
        observations: ArrayLike | None = None,
        *,
        states: ArrayLike | None = None,
        ego_index: int = 0,
        partners: Partners = None,
        method: str = "aail_bounded",
        temperature: float | None = None,
        regret_bound: float | None = None,
        seed: int | None = None,
        alias: str = "production",
        versions: Mapping[str, int] | None = None,
    ) -> ActionColumns:
        body = act_batch_body(
            env, ego_goal, observations, states=states, ego_index=ego_index, partners=partners,
            method=method, temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias, versions=versions,
            columns=True,
        )  # fmt: skip
        return self._columns(body)

    act_batch = rows_of(act_batch_columns)

    def _columns(self, body: dict[str, Any]) -> ActionColumns:
        try:
            response = self._call(self._stub.ActBatch, proto.act_batch_request(body))
        except CoexistError as err:
            raise proto.blame_observations(err) from None
        return proto.columns_from_proto(response.columns)

    def envs(self) -> list[EnvInfo]:
        response = self._call(self._stub.ListEnvs, pb.ListEnvsRequest())
        return [proto.env_from_proto(e) for e in response.envs]

    def health(self) -> Health:
        """The standard gRPC health check of the policy service (ready = SERVING)."""
        stub = health_pb2_grpc.HealthStub(self._channel)
        request = health_pb2.HealthCheckRequest(service=SERVICE_NAME)
        status = self._call(stub.Check, request).status
        name = health_pb2.HealthCheckResponse.ServingStatus.Name(status)
        return Health(live=True, ready=name == "SERVING", detail={"status": name})

    def episode(
        self,
        env: str,
        ego_goal: str,
        *,
        partners: Partners = None,
        infer: Sequence[int] = (),
        method: str = "aail_bounded",
        temperature: float | None = None,
        regret_bound: float | None = None,
        seed: int | None = None,
        alias: str = "production",
        versions: Mapping[str, int] | None = None,
        belief: Mapping[str, Any] | None = None,
    ) -> GrpcEpisode:
        """An `Episode` stream: settings sent with the first step, step t seeded with seed + t."""
        settings = session_body(
            env, ego_goal, partners=partners, infer=infer, method=method,
            temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias, versions=versions, belief=belief,
        )  # fmt: skip
        return GrpcEpisode(self._stub, settings, self._metadata)

    def close(self) -> None:
        self._channel.close()

    def __enter__(self) -> GrpcCoexistClient:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _drain(messages: queue.SimpleQueue[pb.EpisodeStep | None]) -> Iterator[pb.EpisodeStep]:
    while (message := messages.get()) is not None:
        yield message


class GrpcEpisode:
    """One open `Episode` stream (sync): `act()` sends a step and waits for its answer."""

    def __init__(
        self, stub: pb_grpc.PolicyServiceStub, settings: dict[str, Any], metadata: Metadata = None
    ) -> None:
        self._settings: dict[str, Any] | None = settings
        self._outbox: queue.SimpleQueue[pb.EpisodeStep | None] = queue.SimpleQueue()
        self._responses = stub.Episode(_drain(self._outbox), metadata=metadata)
        self.step = 0

    def act(
        self,
        observation: Any = None,
        *,
        state: Any = None,
        ego_index: int = 0,
        observed: Observed = None,
    ) -> Action:
        """One step; `observed`: the inferred partners' actions since the previous step
        (`{1: 3}`; None as an action: the server recovers it). `Action.beliefs` carries the
        beliefs when a partner is inferred."""
        fields = observation_fields(observation, state, ego_index)
        self._outbox.put(proto.episode_step(self._settings, fields, observed_entries(observed)))
        try:
            response = next(self._responses)
        except grpc.RpcError as err:
            raise sdk_error(err) from None
        except StopIteration:
            raise CoexistError("internal", "the server closed the episode stream") from None
        self._settings = None  # only the first step carries the settings
        self.step += 1
        return proto.action_from_proto(response)

    def close(self) -> None:
        """Half-close the stream and wait for the server to end it."""
        self._outbox.put(None)
        try:
            for _ in self._responses:
                pass
        except grpc.RpcError:
            pass  # the stream already failed; act() reported it

    def __enter__(self) -> GrpcEpisode:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
