"""Sessions and episodes: one object whose `step` (or `act`) is one environment step.

| made by                              | over HTTP                                  | over gRPC                  |
|--------------------------------------|--------------------------------------------|----------------------------|
| `client.session(...)` / `create_session(...)` | a REST session (`POST /v1/sessions`, `/steps`, `GET`, `DELETE`) | an `Episode` stream |
| `client.episode(...)`                | `POST /v1/act` per step (a REST session when a partner's goal is inferred) | an `Episode` stream |

    with client.session("particle", "a2", partners={1: None}, seed=0) as session:
        first = session.step(obs_0)                          # SessionStep: an Action + beliefs
        later = session.step(obs_1, observed={1: 3})         # partner 1 took action 3 since
        later.beliefs[0].goal, later.beliefs[0].top          # the belief over its goal

`step(...)` answers a `SessionStep`, `act(...)` the same as a plain `Action`. Every kind seeds
step t with seed + t (the `Episode` stream's rule), so the transports give the same episodes.
A REST session's requests carry `X-Coexist-Affinity` with a random key made at creation (a load
balancer hashing on it sends them all to the replica that holds the session;
docs/architecture.md, "Sessions"), and `expected_step` (`expect_steps=True`), so a retried step
never counts twice: a conflict raises `Conflict`. `info()` asks a REST session's server (`GET`);
an `Episode` stream or an episode of plain `act` calls holds no state a server could be asked
for, so their `info()` answers what the client knows: the next step, the last step's beliefs,
the settings, no id and no expiry (`expires_in_s` infinite: it lives while it is open).
`close()` deletes a REST session (already gone: no error) or half-closes the stream.
"""

from __future__ import annotations

import contextlib
import math
import secrets
from dataclasses import dataclass, fields
from typing import Any

from coexist_client import proto
from coexist_client.bodies import Observed, observation_fields, observed_entries, step_body
from coexist_client.calls import act_exchange
from coexist_client.errors import NotFound
from coexist_client.exchange import Core, Plan, awaiting, blocking
from coexist_client.gen.coexist.v1 import policy_pb2 as pb
from coexist_client.transport import Http, StreamClose, StreamOpen, StreamSend
from coexist_client.types import Action, SessionInfo, SessionStep

AFFINITY_HEADER = "X-Coexist-Affinity"
EPISODE_PATH = "/coexist.v1.PolicyService/Episode"


def new_affinity() -> dict[str, str]:
    return {AFFINITY_HEADER: secrets.token_urlsafe(12)}


@dataclass
class Opened:
    """What opening a session left: its kind and what its steps need."""

    kind: str  # "rest" (a REST session), "stream" (an Episode stream), "act" (POST /v1/act)
    settings: dict[str, Any] | None  # stream: sent with the first step; act: every request's
    handle: Any = None  # stream: the transport's handle
    info: SessionInfo | None = None  # rest: the session as created
    headers: dict[str, str] | None = None  # rest: the affinity header
    expect_steps: bool = True


def open_rest(body: dict[str, Any], expect_steps: bool) -> Plan[Opened]:
    headers = new_affinity()
    data = yield Http("POST", "/v1/sessions", body, headers=headers, idempotent=False)
    info = SessionInfo.from_json(data)
    return Opened("rest", None, info=info, headers=headers, expect_steps=expect_steps)


def open_stream(settings: dict[str, Any]) -> Plan[Opened]:
    handle = yield StreamOpen(EPISODE_PATH, pb.EpisodeStep, pb.ActResponse)
    return Opened("stream", settings, handle=handle)


def as_action(step: Action) -> Action:
    """A `SessionStep` as the plain `Action` it extends."""
    if type(step) is Action:
        return step
    return Action(**{f.name: getattr(step, f.name) for f in fields(Action)})


class SessionCore(Core):
    """A session's state: opened at once (sync clients) or by its first use (`AsyncClient.episode`
    returns before anything is sent, for `async with`)."""

    def __init__(self, transport: Any, opening: Opened | Plan[Opened]) -> None:
        self.transport = transport
        self.opening = opening if not isinstance(opening, Opened) else None
        self.opened: Opened | None = None
        # the REST session as created; other kinds hold no state on the server: a blank one
        self.created = SessionInfo(session_id="", step=0, expires_in_s=math.inf)
        self.session_id, self.path = "", ""
        self.headers: dict[str, str] = {}
        self.next_step, self.expect_steps = 0, True
        self.settings: dict[str, Any] = {}  # what `info()` reports of a session without an id
        self.last_beliefs: tuple[Any, ...] = ()
        if isinstance(opening, Opened):
            self._set(opening)

    def _set(self, opened: Opened) -> None:
        self.opened = opened
        if opened.info is not None:
            self.created = opened.info
        self.session_id = opened.info.session_id if opened.info else ""
        self.headers = opened.headers or {}
        self.path = f"/v1/sessions/{self.session_id}"
        self.next_step = opened.info.step if opened.info else 0  # the next step's index
        self.expect_steps = opened.expect_steps
        self.settings = dict(opened.settings or {})


def ensure_open(core: SessionCore) -> Plan[Opened]:
    """The opened session, opening it first where it is not yet."""
    if core.opened is None:
        assert core.opening is not None
        core._set((yield from core.opening))
        core.opening = None
    assert core.opened is not None
    return core.opened


def step(
    core: SessionCore,
    observation: Any = None,
    *,
    state: Any = None,
    ego_index: int = 0,
    observed: Observed = None,
) -> Plan[SessionStep]:
    """One step: `observed` = the inferred partners' actions since the previous step (`{1: 3}`;
    None as an action: the server recovers it from the observations)."""
    opened = yield from ensure_open(core)
    t = core.next_step
    if opened.kind == "rest":
        expected = t if core.expect_steps else None
        body = step_body(
            observation,
            state=state,
            ego_index=ego_index,
            observed=observed,
            expected_step=expected,
        )
        data = yield Http("POST", f"{core.path}/steps", body, headers=core.headers)
        answer = SessionStep.from_json(data)
        core.next_step = answer.step + 1
        return answer
    fields_ = observation_fields(observation, state, ego_index)
    if opened.kind == "stream":
        message = proto.episode_step(opened.settings, fields_, observed_entries(observed))
        action = proto.action_from_proto((yield StreamSend(opened.handle, message)))
        opened.settings = None  # only the first step carries the settings
    else:
        settings = dict(opened.settings or {})
        if settings["seed"] is not None:
            settings["seed"] += t
        action = yield from act_exchange(core.transport, {**settings, **fields_})
    core.next_step = t + 1
    core.last_beliefs = action.beliefs
    return SessionStep(**{f.name: getattr(action, f.name) for f in fields(Action)}, step=t)


def act(
    core: SessionCore,
    observation: Any = None,
    *,
    state: Any = None,
    ego_index: int = 0,
    observed: Observed = None,
) -> Plan[Action]:
    """`step`, answered as a plain `Action` (beliefs included where a partner is inferred)."""
    answer = yield from step(core, observation, state=state, ego_index=ego_index, observed=observed)
    return answer if core.opened is not None and core.opened.kind == "rest" else as_action(answer)


def info(core: SessionCore) -> Plan[SessionInfo]:
    """The REST session as the server holds it (next step, beliefs, idle time left); a stream
    or an episode of `act` calls as the client knows it (module docstring)."""
    if (yield from ensure_open(core)).kind != "rest":
        return SessionInfo(
            session_id="",
            step=core.next_step,
            expires_in_s=math.inf,
            beliefs=core.last_beliefs,
            settings=core.settings,
        )
    return SessionInfo.from_json((yield Http("GET", core.path, headers=core.headers)))


def close(core: SessionCore) -> Plan[None]:
    """Delete the REST session (already gone: no error), or half-close the Episode stream."""
    opened = core.opened
    if opened is None:  # never opened: nothing to close
        return
    if opened.kind == "stream":
        yield StreamClose(opened.handle)
    elif opened.kind == "rest" and opened.info is not None:
        opened.info = None  # once
        with contextlib.suppress(NotFound):  # already gone
            yield Http("DELETE", core.path, headers=core.headers)


class Session(SessionCore):
    """A session or episode (sync); see the module docstring."""

    step = blocking(step)
    act = blocking(act)
    info = blocking(info)
    close = blocking(close)

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


class AsyncSession(SessionCore):
    """A session or episode (async): the same methods, awaited; `aclose()` to close."""

    step = awaiting(step)
    act = awaiting(act)
    info = awaiting(info)
    aclose = awaiting(close)

    _open = awaiting(ensure_open)

    async def __aenter__(self) -> AsyncSession:
        await self._open()
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.aclose()
