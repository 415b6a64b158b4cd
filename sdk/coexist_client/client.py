"""The coexist client: one set of methods over HTTP or gRPC, sync (`Client`) or async
(`AsyncClient`).

    with Client("http://127.0.0.1:8000") as client:        # or "grpc://127.0.0.1:50051"
        a = client.act("particle", "a2", obs, partners={1: "b3"}, seed=7)
        a.action, a.probs, a.diagnostics.task_weight

| method                  | REST                     | gRPC            | returns          |
|-------------------------|--------------------------|-----------------|------------------|
| `act(...)`              | `POST /v1/act`           | `Act`           | `Action`         |
| `act_batch(...)`        | `POST /v1/act:batch`     | `ActBatch`      | `list[Action]`   |
| `act_batch_columns(...)`| `POST /v1/act:batch`     | `ActBatch`      | `ActionColumns`  |
| `envs()`                | `GET /v1/envs`           | `ListEnvs`      | `list[EnvInfo]`  |
| `health()`              | `/healthz`, `/readyz`    | health checking | `Health`         |
| `session(...)`          | `POST /v1/sessions`      | `Episode`       | `Session`        |
| `episode(...)`          | `POST /v1/act` per step  | `Episode`       | `Session`        |

The transport follows the address (`coexist_client.address`, the parser the `coexist` command
line uses too): `http://` or `https://` speak REST, `grpc://`, `grpcs://` or `unix:/path` gRPC,
and a bare `host:port` the `protocol=` given, REST without one. Options: `timeout` (seconds per request),
`token` (a bearer token on every request and call), `retry` (`Retry`: attempts and backoff on
connection errors, HTTP 503 and gRPC UNAVAILABLE); HTTP: `headers`, `verify` (a CA file or
False), `transport` (an httpx transport); gRPC: `tls`, `root_certificates`, `options` (channel
options). `CoexistClient`, `GrpcCoexistClient`, `AsyncCoexistClient` and
`AsyncGrpcCoexistClient` are the same clients with the protocol fixed.
Partners: `{1: "b3"}`, `{1: {"b3": 0.7, "c": 0.3}}`, a list of PartnerSpec-like objects, or
(sessions, episodes) `{1: None}` to infer partner 1's goal online.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Concatenate, ParamSpec, TypeVar, Unpack

from coexist_client.address import Protocol, parse_address
from coexist_client.bodies import Settings, act_batch_body, act_body, session_body, shows_settings
from coexist_client.calls import act_exchange, columns_exchange, envs_exchange, health_exchange
from coexist_client.exchange import (
    AsyncClosing,
    Closing,
    Core,
    Plan,
    Retry,
    awaiting,
    awaiting_opening,
    blocking,
    opening,
)
from coexist_client.sessions import AsyncSession, Opened, Session, open_rest, open_stream
from coexist_client.transport import GrpcTransport, HttpTransport, Verify
from coexist_client.types import Action, ActionColumns, EnvInfo, Health

DEFAULT_URL = "http://127.0.0.1:8000"
P = ParamSpec("P")
T = TypeVar("T")
DEFAULT_TARGET = "127.0.0.1:50051"


def protocol_of(url: str, protocol: Protocol | None = None) -> Protocol:
    """The protocol of address `url` (`coexist_client.address`): its scheme's, else
    `protocol`, else REST; a `ValueError` for an address that cannot be one."""
    return parse_address(url, protocol).protocol


class ClientCore(Core):
    def __init__(
        self,
        url: str = DEFAULT_URL,
        *,
        protocol: Protocol | None = None,
        timeout: float | None = 10.0,
        token: str | None = None,
        retry: Retry = Retry(),
        headers: dict[str, str] | None = None,
        verify: Verify = True,
        transport: Any = None,
        tls: bool = False,
        root_certificates: str | Path | None = None,
        options: list[tuple[str, Any]] | None = None,
        aio: bool = False,
    ) -> None:
        address = parse_address(url, protocol)
        if address.protocol == "http":
            self.transport: HttpTransport | GrpcTransport = HttpTransport(
                address.target,
                aio=aio,
                timeout=timeout,
                token=token,
                headers=headers,
                verify=verify,
                transport=transport,
                retry=retry,
            )
        else:
            self.transport = GrpcTransport(
                url,
                aio=aio,
                timeout=timeout,
                token=token,
                tls=tls,
                root_certificates=root_certificates,
                options=options,
                retry=retry,
            )


def _sent(
    name: str,
    body: Callable[P, dict[str, Any]],
    exchange: Callable[[Any, dict[str, Any]], Plan[T]],
    doc: str,
) -> Callable[Concatenate[ClientCore, P], Plan[T]]:
    """The plan `name`: `body(...)` built and sent by `exchange`. Signed as `body` with `core`
    first and the exchange's result, so the methods made of it show the real parameters."""

    def plan(core: ClientCore, /, *args: P.args, **kwargs: P.kwargs) -> Plan[T]:
        return (yield from exchange(core.transport, body(*args, **kwargs)))

    plan.__name__ = plan.__qualname__ = name
    plan.__doc__ = doc
    signature = inspect.signature(body)
    core = inspect.Parameter(
        "core", inspect.Parameter.POSITIONAL_OR_KEYWORD, annotation="ClientCore"
    )
    plan.__signature__ = signature.replace(  # type: ignore[attr-defined]
        parameters=[core, *signature.parameters.values()],
        return_annotation=inspect.signature(exchange).return_annotation,
    )
    return plan


act = _sent("act", act_body, act_exchange, "One action for one observation (or state + ego_index).")
act_batch_columns = _sent(
    "act_batch_columns",
    act_batch_body,
    columns_exchange,
    """Many observations (or states + ego_index) in one vectorised request, answered as arrays,
    one per field (the server's columnar format).""",
)


def _rows(columns: Callable[P, Plan[ActionColumns]]) -> Callable[P, Plan[list[Action]]]:
    """`act_batch` from `act_batch_columns`: the same parameters, one `Action` a row."""

    def act_batch(*args: P.args, **kwargs: P.kwargs) -> Plan[list[Action]]:
        return (yield from columns(*args, **kwargs)).to_actions()

    act_batch.__doc__ = "One action per observation (or per state), in order, from one request."
    signature = inspect.signature(columns)
    act_batch.__signature__ = signature.replace(  # type: ignore[attr-defined]
        return_annotation="Plan[list[Action]]"
    )
    return act_batch


act_batch = _rows(act_batch_columns)


def envs(core: ClientCore) -> Plan[list[EnvInfo]]:
    """The environments the server knows: goals, observation layouts, action meanings."""
    return (yield from envs_exchange(core.transport))


def health(core: ClientCore) -> Plan[Health]:
    """Liveness and readiness (HTTP: `/healthz`, `/readyz`; gRPC: the health check)."""
    return (yield from health_exchange(core.transport))


@shows_settings
def open_session(
    core: ClientCore,
    env: str,
    ego_goal: str,
    *,
    infer: Sequence[int] = (),
    belief: Mapping[str, Any] | None = None,
    expect_steps: bool = True,
    episode: bool = False,
    **settings: Unpack[Settings],
) -> Plan[Opened]:
    """A session: settings given once, then `step(obs)` (or `act(obs)`) per step, step t
    seeded with seed + t. Partners' goals are announced, or inferred by the server from their
    actions: `partners={1: None}` (uniform prior) or `infer=[1]` (the announced goal is the
    prior); `belief`: forgetting, floor, temperature, noise, blend_mass, blend_max_goals,
    prune_below, prune_error (left out: the server's). Over gRPC an `Episode` stream; over HTTP a REST session, or with `episode`
    and no goal inferred plain `POST /v1/act` per step (no state on the server)."""
    body = session_body(env, ego_goal, infer=infer, belief=belief, **settings)
    if core.transport.grpc:
        return (yield from open_stream(body))
    inferring = any(p.get("infer") for p in body["partners"]) or belief is not None
    if episode and not inferring:
        fields = {k: v for k, v in body.items() if k != "belief"}
        fields["partners"] = [
            {k: v for k, v in p.items() if k != "infer"} for p in body["partners"]
        ]
        return Opened("act", fields)
    return (yield from open_rest(body, expect_steps))


class Client(ClientCore, Closing):
    """The synchronous client; see the module docstring."""

    act = blocking(act)
    act_batch = blocking(act_batch)
    act_batch_columns = blocking(act_batch_columns)
    envs = blocking(envs)
    health = blocking(health)
    session = opening(open_session, Session)
    create_session = session

    def episode(self, env: str, ego_goal: str, **settings: Any) -> Session:
        """`session(..., episode=True)`: one episode, `act(obs)` per step."""
        return self.session(env, ego_goal, episode=True, **settings)


class AsyncClient(ClientCore, AsyncClosing):
    """The asynchronous client: the same methods, awaited (`aclose()` to close). Over gRPC it
    holds a `grpc.aio` channel: create it inside the event loop that uses it."""

    def __init__(self, url: str = DEFAULT_URL, **options: Any) -> None:
        super().__init__(url, aio=True, **options)

    act = awaiting(act)
    act_batch = awaiting(act_batch)
    act_batch_columns = awaiting(act_batch_columns)
    envs = awaiting(envs)
    health = awaiting(health)
    session = awaiting_opening(open_session, AsyncSession)
    create_session = session

    def episode(self, env: str, ego_goal: str, **settings: Any) -> AsyncSession:
        """As `Client.episode`; the episode opens with `async with` or its first step (nothing
        is sent before), so `async with client.episode(...) as ep` needs no await."""
        # a wrong argument fails here, as in any call; the plan runs from `async with` or a step
        inspect.signature(open_session).bind(self, env, ego_goal, episode=True, **settings)
        plan = open_session(self, env, ego_goal, episode=True, **settings)
        return AsyncSession(self.transport, plan)


class CoexistClient(Client):
    """`Client` over REST."""

    def __init__(self, base_url: str = DEFAULT_URL, **options: Any) -> None:
        super().__init__(base_url, protocol="http", **options)


class GrpcCoexistClient(Client):
    """`Client` over gRPC."""

    def __init__(self, target: str = DEFAULT_TARGET, **options: Any) -> None:
        super().__init__(target, protocol="grpc", **options)


class AsyncCoexistClient(AsyncClient):
    """`AsyncClient` over REST."""

    def __init__(self, base_url: str = DEFAULT_URL, **options: Any) -> None:
        super().__init__(base_url, protocol="http", **options)


class AsyncGrpcCoexistClient(AsyncClient):
    """`AsyncClient` over gRPC."""

    def __init__(self, target: str = DEFAULT_TARGET, **options: Any) -> None:
        super().__init__(target, protocol="grpc", **options)
