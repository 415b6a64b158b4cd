"""REST sessions across server processes: two `coexist serve` replicas on one PostgreSQL model
store and one Redis session store, the first with two workers. One session is stepped through
both in turn (a new connection per request, so the first replica's two workers share it too),
then the replica that answered last is killed (SIGKILL) and the session goes on on the other:
every answer equals the one a single process gives for the same settings, seeds and inputs."""

from __future__ import annotations

import secrets
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from replica_cluster import pg_schema_url, running, server_env, start_server
from session_backends import drop_namespace, redis_url
from session_zoo import random_observation, register_session_zoo

from model_store.sql import SqlModelStore
from services.engine import InferenceEngine
from services.rest import install_error_handlers, router, sessions_router
from services.sessions.codec import SessionCodec

pytestmark = [pytest.mark.postgres, pytest.mark.redis]
PARTNERS = (1, 2, 3, 4)
CREATE = {
    "env": "particle",
    "ego_goal": "a2",
    "partners": [{"index": i, "infer": True} for i in PARTNERS],
    "method": "aail_budget",  # the budget's state travels with the session too
    "budget": 0.5,
    "seed": 21,
}
STEPS = 10
KILL_AFTER = 5  # the replica that answered step KILL_AFTER is killed
KILLED, SURVIVOR = KILL_AFTER % 2, 1 - KILL_AFTER % 2


@pytest.fixture
def zoo_url() -> Iterator[str]:
    with pg_schema_url() as url:
        register_session_zoo(url)
        yield url


def step_bodies() -> list[dict[str, Any]]:
    rng = np.random.default_rng(8)
    bodies = []
    for t in range(STEPS):
        body: dict[str, Any] = {
            "observation": random_observation(rng, len(PARTNERS) + 1).tolist(),
            "expected_step": t,
        }
        if t:
            body["observed"] = [{"index": i, "action": int(rng.integers(5))} for i in PARTNERS]
        bodies.append(body)
    return bodies


def comparable(answer: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in answer.items() if k != "session_id"}


def single_process_answers(zoo_url: str) -> list[dict[str, Any]]:
    """The answers of one process keeping the session in its memory (the default store)."""
    app = FastAPI()
    app.include_router(router)
    app.include_router(sessions_router)
    install_error_handlers(app)
    with SqlModelStore(zoo_url) as store:
        app.state.engine = InferenceEngine(store)
        with TestClient(app) as client:
            session_id = client.post("/v1/sessions", json=CREATE).json()["session_id"]
            return [
                comparable(client.post(f"/v1/sessions/{session_id}/steps", json=b).json())
                for b in step_bodies()
            ]


@pytest.mark.slow  # two server processes (one of two workers) start: ~20-40 s on 2 cores
def test_a_session_outlives_the_replica_that_served_it(zoo_url: str, tmp_path: Path) -> None:
    expected = single_process_answers(zoo_url)
    secret = secrets.token_hex(24)
    with redis_url() as session_url:
        env = server_env(
            zoo_url,
            tmp_path,
            COEXIST_SESSION_STORE_URL=session_url,
            COEXIST_SESSION_SECRET=secret,
        )
        replicas = [
            start_server("a", env, tmp_path, ("serve", "--no-bootstrap", "--workers", "2")),
            start_server("b", env, tmp_path),
        ]
        try:
            with running(replicas):
                created = httpx.post(f"{replicas[0].http_url}/v1/sessions", json=CREATE)
                assert created.status_code == 201, created.text
                session_id = created.json()["session_id"]
                got = []
                for t, body in enumerate(step_bodies()):
                    # alternately, until the kill; then the survivor alone
                    server = replicas[t % 2 if t <= KILL_AFTER else SURVIVOR]
                    answer = httpx.post(
                        f"{server.http_url}/v1/sessions/{session_id}/steps", json=body, timeout=30
                    )
                    assert answer.status_code == 200, answer.text
                    got.append(comparable(answer.json()))
                    if t == KILL_AFTER:
                        killed = replicas[KILLED].process
                        killed.send_signal(signal.SIGKILL)
                        killed.wait(timeout=30)
                assert got == expected
                info = httpx.get(f"{replicas[SURVIVOR].http_url}/v1/sessions/{session_id}").json()
                assert info["step"] == STEPS
                assert [b["updates"] for b in info["beliefs"]] == [STEPS - 1] * len(PARTNERS)
        finally:
            drop_namespace(session_url, SessionCodec(secret.encode()).namespace())
