"""Sessions in the SDK: the HTTP clients' `create_session` (sync against a live server, async over
ASGI) and the gRPC clients' episodes with `observed`, all giving the session core's answers;
typed results and errors; the affinity header on every request of a session."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest
from coexist_client import (
    AsyncCoexistClient,
    AsyncGrpcCoexistClient,
    CoexistClient,
    Conflict,
    GrpcCoexistClient,
    InvalidArgument,
    NotFound,
    ResourceExhausted,
    SessionStep,
)
from coexist_client.errors import error_for_http
from coexist_client.sessions import AFFINITY_HEADER
from fastapi import FastAPI
from grpc_live_server import live_grpc_server
from http_live_server import inference_app, live_http_server
from session_zoo import random_observation, session_zoo_template

from model_store.sql import SqlModelStore
from policy.belief import BeliefConfig
from services.engine import InferenceEngine
from services.rest import sessions_router
from services.sessions import Observed, Session, SessionPartner, SessionSettings

ACTIONS = [None, 3, 3, 1, 0]


@pytest.fixture(scope="module")
def engine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        yield InferenceEngine(store)


@pytest.fixture(scope="module")
def app(engine: InferenceEngine) -> FastAPI:
    app = inference_app(engine)
    app.include_router(sessions_router)
    return app


@pytest.fixture(scope="module")
def base_url(app: FastAPI) -> Iterator[str]:
    with live_http_server(app) as url:
        yield url


class RecordingTransport(httpx.BaseTransport):
    """A real HTTP transport that remembers each request's method, path and headers."""

    def __init__(self) -> None:
        self.inner = httpx.HTTPTransport()
        self.seen: list[tuple[str, str, httpx.Headers]] = []

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        self.seen.append((request.method, request.url.path, request.headers))
        return self.inner.handle_request(request)


def observations_of(seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [random_observation(rng) for _ in ACTIONS]


def core_answers(
    engine: InferenceEngine, obs: list[np.ndarray], belief: BeliefConfig | None = None
) -> list[Any]:
    settings = SessionSettings(
        "particle", "a2", (SessionPartner(1),), seed=3, belief=belief or BeliefConfig()
    )
    session = Session(engine, settings)
    return [
        session.step(o, [] if a is None else [Observed(1, a)])
        for o, a in zip(obs, ACTIONS, strict=True)
    ]


def assert_same(got: Any, want: Any) -> None:
    assert got.probs == tuple(want.result.probs)
    assert got.action == want.result.action
    (belief,) = got.beliefs
    (wanted,) = want.beliefs
    assert (belief.index, belief.top, belief.entropy) == (wanted.index, wanted.top, wanted.entropy)
    assert (belief.observed_action, belief.updates) == (wanted.observed_action, wanted.updates)


def test_sync_sessions_round_trip(base_url: str, engine: InferenceEngine) -> None:
    obs = observations_of(0)
    transport = RecordingTransport()
    with CoexistClient(base_url, transport=transport) as client:
        session = client.create_session("particle", "a2", partners={1: None}, seed=3)
        assert session.created.step == 0 and session.created.beliefs[0].updates == 0
        answers = [
            session.step(o, observed=None if a is None else {1: a})
            for o, a in zip(obs, ACTIONS, strict=True)
        ]
        for got, want in zip(answers, core_answers(engine, obs), strict=True):
            assert isinstance(got, SessionStep) and got.step == want.step
            assert got.session_id == session.session_id
            assert_same(got, want)
        info = session.info()
        assert info.step == len(ACTIONS) and info.beliefs == answers[-1].beliefs
        assert info.settings["partners"][0]["infer"] is True
        session.close()
        with pytest.raises(NotFound) as err:
            session.info()
        assert err.value.field == "session_id"
        session.close()  # already gone: no error
    keys = {headers.get(AFFINITY_HEADER) for _, path, headers in transport.seen}
    assert len(keys) == 1 and None not in keys  # one key on every request of the session
    assert [method for method, _, _ in transport.seen][:2] == ["POST", "POST"]


def test_an_announced_goal_as_prior_and_belief_settings(base_url: str) -> None:
    with CoexistClient(base_url) as client:
        session = client.create_session(
            "particle", "a2", partners={1: "e4"}, infer=[1], belief={"floor": 0.0}
        )
        (belief,) = session.created.beliefs
        assert belief.goal == "e4" and belief.top[0][1] == pytest.approx(0.9)
        assert session.info().settings["belief"]["floor"] == 0.0
        session.close()


def test_the_likelihood_noise_reaches_the_server_over_http_and_grpc(
    base_url: str, engine: InferenceEngine
) -> None:
    obs = observations_of(4)
    want = core_answers(engine, obs, BeliefConfig(noise=0.2))
    assert want[-1].beliefs != core_answers(engine, obs)[-1].beliefs  # the noise matters
    with (
        CoexistClient(base_url) as client,
        client.create_session(
            "particle", "a2", partners={1: None}, seed=3, belief={"noise": 0.2}
        ) as session,
    ):
        assert session.info().settings["belief"]["noise"] == 0.2
        for o, a, w in zip(obs, ACTIONS, want, strict=True):
            assert_same(session.step(o, observed=None if a is None else {1: a}), w)
    with (
        live_grpc_server(engine.store) as live,
        GrpcCoexistClient(live.target) as grpc_client,
        grpc_client.episode(
            "particle", "a2", partners={1: None}, seed=3, belief={"noise": 0.2}
        ) as episode,
    ):
        for o, a, w in zip(obs, ACTIONS, want, strict=True):
            assert_same(episode.act(o, observed=None if a is None else {1: a}), w)


def test_a_replayed_step_is_a_conflict(base_url: str) -> None:
    with (
        CoexistClient(base_url) as client,
        client.create_session("particle", "a2", partners={1: None}) as session,
    ):
        session.step(np.zeros(8))
        session.next_step = 0  # as if the answer to step 0 had been lost and it is sent again
        with pytest.raises(Conflict) as err:
            session.step(np.zeros(8))
        assert (err.value.code, err.value.field) == ("aborted", "expected_step")
        with pytest.raises(InvalidArgument) as bad:
            client.create_session("particle", "a2", partners={1: None}).step(
                np.zeros(8), observed={1: 9}
            )
        assert bad.value.field == "observed"  # step 0 has no previous observation


def test_bad_forms_are_refused_before_sending() -> None:
    client = CoexistClient("http://127.0.0.1:9")  # never reached
    with pytest.raises(InvalidArgument) as err:
        client.act("particle", "a2", np.zeros(8), partners={1: None})
    assert err.value.field == "partners[1]" and "sessions" in err.value.message
    with pytest.raises(InvalidArgument) as err:
        client.create_session("particle", "a2", belief=0.9)  # type: ignore[arg-type]
    assert err.value.field == "belief"
    assert isinstance(error_for_http(429, "full", None), ResourceExhausted)


def test_async_sessions_match_the_core(app: FastAPI, engine: InferenceEngine) -> None:
    obs = observations_of(1)

    async def main() -> list[SessionStep]:
        transport = httpx.ASGITransport(app=app)
        async with AsyncCoexistClient("http://asgi", transport=transport) as client:
            async with await client.create_session(
                "particle", "a2", partners=[{"index": 1, "infer": True}], seed=3
            ) as session:
                answers = [
                    await session.step(
                        o, observed=None if a is None else [{"index": 1, "action": a}]
                    )
                    for o, a in zip(obs, ACTIONS, strict=True)
                ]
                assert (await session.info()).step == len(ACTIONS)
            return answers

    for got, want in zip(asyncio.run(main()), core_answers(engine, obs), strict=True):
        assert_same(got, want)


def test_grpc_episodes_with_observed_match_the_core(engine: InferenceEngine) -> None:
    obs = observations_of(2)
    want = core_answers(engine, obs)
    with live_grpc_server(engine.store) as live:
        with (
            GrpcCoexistClient(live.target) as client,
            client.episode("particle", "a2", partners={1: None}, seed=3) as episode,
        ):
            assert episode.info().step == 0
            for o, a, w in zip(obs, ACTIONS, want, strict=True):
                last = episode.act(o, observed=None if a is None else {1: a})
                assert_same(last, w)
            # a stream holds nothing a server could be asked for: what the client knows
            info = episode.info()
            assert info.step == len(ACTIONS) and info.beliefs == last.beliefs
            assert info.beliefs[0].updates == want[-1].beliefs[0].updates
            assert info.session_id == "" and info.expires_in_s == float("inf")
            assert info.settings  # the settings the stream was opened with

        async def main() -> list[Any]:
            async with (
                AsyncGrpcCoexistClient(live.target) as client,
                client.episode("particle", "a2", infer=[1], seed=3) as episode,
            ):
                return [
                    await episode.act(o, observed=None if a is None else {1: a})
                    for o, a in zip(obs, ACTIONS, strict=True)
                ]

        for got, w in zip(asyncio.run(main()), want, strict=True):
            assert_same(got, w)
