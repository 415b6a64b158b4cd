"""`AsyncGrpcCoexistClient`: the gRPC client on `grpc.aio`, the same methods as
`GrpcCoexistClient`, awaited.

    async with AsyncGrpcCoexistClient("127.0.0.1:50051") as client:
        a = await client.act("particle", "a2", obs, partners={1: "b3"})
        async with client.episode("particle", "a2", partners={1: "b3"}, seed=0) as ep:
            a = await ep.act(obs)

A `grpc.aio` channel belongs to the event loop it was created on: create the client inside the
loop that uses it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
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
from services.sdk.errors import CoexistError
from services.sdk.grpc_client import DEFAULT_TARGET, SERVICE_NAME, sdk_error
from services.sdk.types import Action, ActionColumns, EnvInfo, Health, async_rows_of


class AsyncGrpcCoexistClient:
    """Asynchronous gRPC client; see the module docstring."""

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
            target, tls=tls, root_certificates=root_certificates, options=options, aio=True
        )
        self._stub = pb_grpc.PolicyServiceStub(self._channel)
        self._timeout = timeout
        self._metadata = grpc_metadata(token)

    async def _call(self, method: Any, request: Any) -> Any:
        try:
            return await method(request, timeout=self._timeout, metadata=self._metadata)
        except grpc.RpcError as err:
            raise sdk_error(err) from None

    async def act(
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
        response = await self._call(self._stub.Act, proto.act_request(body))
        return proto.action_from_proto(response)

    async def act_batch_columns(
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
        return await self._columns(body)

    act_batch = async_rows_of(act_batch_columns)

    async def _columns(self, body: dict[str, Any]) -> ActionColumns:
        try:
            response = await self._call(self._stub.ActBatch, proto.act_batch_request(body))
        except CoexistError as err:
            raise proto.blame_observations(err) from None
        return proto.columns_from_proto(response.columns)

    async def envs(self) -> list[EnvInfo]:
        response = await self._call(self._stub.ListEnvs, pb.ListEnvsRequest())
        return [proto.env_from_proto(e) for e in response.envs]

    async def health(self) -> Health:
        stub = health_pb2_grpc.HealthStub(self._channel)
        request = health_pb2.HealthCheckRequest(service=SERVICE_NAME)
        status = (await self._call(stub.Check, request)).status
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
    ) -> AsyncGrpcEpisode:
        settings = session_body(
            env, ego_goal, partners=partners, infer=infer, method=method,
            temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias, versions=versions, belief=belief,
        )  # fmt: skip
        return AsyncGrpcEpisode(self._stub, settings, self._metadata)

    async def aclose(self) -> None:
        await self._channel.close()

    async def __aenter__(self) -> AsyncGrpcCoexistClient:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.aclose()


class AsyncGrpcEpisode:
    """One open `Episode` stream on grpc.aio."""

    def __init__(
        self, stub: pb_grpc.PolicyServiceStub, settings: dict[str, Any], metadata: Metadata = None
    ) -> None:
        self._settings: dict[str, Any] | None = settings
        self._call = stub.Episode(metadata=metadata)
        self.step = 0

    async def act(
        self,
        observation: Any = None,
        *,
        state: Any = None,
        ego_index: int = 0,
        observed: Observed = None,
    ) -> Action:
        fields = observation_fields(observation, state, ego_index)
        message = proto.episode_step(self._settings, fields, observed_entries(observed))
        try:
            await self._call.write(message)
            response = await self._call.read()
        except grpc.RpcError as err:
            raise sdk_error(err) from None
        if response is grpc.aio.EOF:
            raise CoexistError("internal", "the server closed the episode stream")
        self._settings = None
        self.step += 1
        return proto.action_from_proto(response)

    async def aclose(self) -> None:
        """Half-close the stream and wait for the server to end it."""
        try:
            await self._call.done_writing()
            while await self._call.read() is not grpc.aio.EOF:
                pass
        except grpc.RpcError:
            pass  # the stream already failed; act() reported it

    async def __aenter__(self) -> AsyncGrpcEpisode:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.aclose()
