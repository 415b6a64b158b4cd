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

The transport follows the URL: `http://` or `https://` speak REST, `grpc://`, `grpcs://` or a
bare `host:port` gRPC (`protocol=` overrides). Options: `timeout` (seconds per request),
`token` (a bearer token on every request and call), `retry` (`Retry`: attempts and backoff on
connection errors, HTTP 503 and gRPC UNAVAILABLE); HTTP: `headers`, `verify` (a CA file or
False), `transport` (an httpx transport); gRPC: `tls`, `root_certificates`, `options` (channel
options). `CoexistClient`, `GrpcCoexistClient`, `AsyncCoexistClient` and
`AsyncGrpcCoexistClient` are the same clients with the protocol fixed.
Partners: `{1: "b3"}`, `{1: {"b3": 0.7, "c": 0.3}}`, a list of PartnerSpec-like objects, or
(sessions, episodes) `{1: None}` to infer partner 1's goal online.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

from numpy.typing import ArrayLike

from coexist_client.bodies import (
    Partners,
    act_batch_body,
    act_body,
    episode_settings,
    session_body,
)
from coexist_client.calls import act_exchange, columns_exchange, envs_exchange, health_exchange
from coexist_client.exchange import AsyncClosing, Closing, Core, Plan, Retry, awaiting, blocking
from coexist_client.sessions import AsyncSession, Opened, Session, open_rest, open_stream
from coexist_client.transport import GrpcTransport, HttpTransport, Verify
from coexist_client.types import Action, ActionColumns, EnvInfo, Health

DEFAULT_URL = "http://127.0.0.1:8000"
DEFAULT_TARGET = "127.0.0.1:50051"
Protocol = Literal["http", "grpc"]


def protocol_of(url: str) -> Protocol:
    """`http` for an http(s):// URL, `grpc` for grpc(s):// or a bare `host:port`."""
    return "http" if url.startswith(("http://", "https://")) else "grpc"


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
        if (protocol or protocol_of(url)) == "http":
            self.transport: HttpTransport | GrpcTransport = HttpTransport(
                url, aio=aio, timeout=timeout, token=token, headers=headers, verify=verify,
                transport=transport, retry=retry,
            )  # fmt: skip
        else:
            self.transport = GrpcTransport(
                url, aio=aio, timeout=timeout, token=token, tls=tls,
                root_certificates=root_certificates, options=options, retry=retry,
            )  # fmt: skip


def act(
    core: ClientCore,
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
) -> Plan[Action]:
    """One action for one observation (or state + ego_index)."""
    body = act_body(
        env, ego_goal, observation, state=state, ego_index=ego_index, partners=partners,
        method=method, temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias,
        versions=versions,
    )  # fmt: skip
    return (yield from act_exchange(core.transport, body))


def act_batch_columns(
    core: ClientCore,
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
) -> Plan[ActionColumns]:
    """Many observations (or states + ego_index) in one vectorised request, answered as arrays,
    one per field (the server's columnar format)."""
    body = act_batch_body(
        env, ego_goal, observations, states=states, ego_index=ego_index, partners=partners,
        method=method, temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias,
        versions=versions, columns=True,
    )  # fmt: skip
    return (yield from columns_exchange(core.transport, body))


def act_batch(
    core: ClientCore,
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
) -> Plan[list[Action]]:
    """One action per observation (or per state), in order, from one vectorised request."""
    columns = yield from act_batch_columns(
        core, env, ego_goal, observations, states=states, ego_index=ego_index, partners=partners,
        method=method, temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias,
        versions=versions,
    )  # fmt: skip
    return columns.to_actions()


def envs(core: ClientCore) -> Plan[list[EnvInfo]]:
    """The environments the server knows: goals, observation layouts, action meanings."""
    return (yield from envs_exchange(core.transport))


def health(core: ClientCore) -> Plan[Health]:
    """Liveness and readiness (HTTP: `/healthz`, `/readyz`; gRPC: the health check)."""
    return (yield from health_exchange(core.transport))


def open_session(
    core: ClientCore,
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
    expect_steps: bool = True,
) -> Plan[Opened]:
    """A session whose partners' goals the server may infer from their actions: `partners={1:
    None}` (uniform prior) or `infer=[1]` (the announced goal is the prior); `belief`:
    forgetting, floor, temperature, blend_mass, blend_max_goals (left out: the server's)."""
    body = session_body(
        env, ego_goal, partners=partners, infer=infer, method=method, temperature=temperature,
        regret_bound=regret_bound, seed=seed, alias=alias, versions=versions, belief=belief,
    )  # fmt: skip
    if core.transport.grpc:
        return (yield from open_stream(body))
    return (yield from open_rest(body, expect_steps))


def open_episode(
    core: ClientCore,
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
) -> Plan[Opened]:
    """One episode: settings given once, then `act(obs)` per step, step t seeded with seed + t
    (an Episode stream over gRPC; over HTTP `POST /v1/act` per step, or a REST session where a
    partner's goal is inferred)."""
    session = session_body(
        env, ego_goal, partners=partners, infer=infer, method=method, temperature=temperature,
        regret_bound=regret_bound, seed=seed, alias=alias, versions=versions, belief=belief,
    )  # fmt: skip
    if core.transport.grpc:
        return (yield from open_stream(session))
    if any(p.get("infer") for p in session["partners"]) or belief is not None:
        return (yield from open_rest(session, True))
    settings = episode_settings(
        env, ego_goal, partners=partners, method=method, temperature=temperature,
        regret_bound=regret_bound, seed=seed, alias=alias, versions=versions,
    )  # fmt: skip
    return Opened("act", settings)


class Client(ClientCore, Closing):
    """The synchronous client; see the module docstring."""

    act = blocking(act)
    act_batch = blocking(act_batch)
    act_batch_columns = blocking(act_batch_columns)
    envs = blocking(envs)
    health = blocking(health)
    _open_session = blocking(open_session)
    _open_episode = blocking(open_episode)

    def session(self, env: str, ego_goal: str, **settings: Any) -> Session:
        """A session (`open_session`'s settings): REST over HTTP, an Episode stream over gRPC."""
        return Session(self.transport, self._open_session(env, ego_goal, **settings))

    create_session = session

    def episode(self, env: str, ego_goal: str, **settings: Any) -> Session:
        """One episode (`open_episode`'s settings); `act(obs)` per step."""
        return Session(self.transport, self._open_episode(env, ego_goal, **settings))


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
    _open_session = awaiting(open_session)

    async def session(self, env: str, ego_goal: str, **settings: Any) -> AsyncSession:
        """As `Client.session`, awaited."""
        return AsyncSession(self.transport, await self._open_session(env, ego_goal, **settings))

    create_session = session

    def episode(self, env: str, ego_goal: str, **settings: Any) -> AsyncSession:
        """As `Client.episode`; the episode opens with `async with` or its first step."""
        return AsyncSession(self.transport, open_episode(self, env, ego_goal, **settings))


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
