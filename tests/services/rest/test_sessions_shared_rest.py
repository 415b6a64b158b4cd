"""The session routes over a shared session store (Redis, `COEXIST_SESSION_STORE_URL`): two apps
stand for two workers; sessions work with several workers; a foreign id is a 404, a tampered
record a 410, a store that does not answer a 503, each naming the cause, never a 500; the secret
is required and never shown."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from pydantic import SecretStr
from serve_process import free_port
from session_backends import drop_namespace, new_secret, redis_url
from session_zoo import session_zoo_template

from model_store.sql import SqlModelStore
from services.engine import InferenceEngine
from services.rest import install_error_handlers, router, sessions_router
from services.settings import InsecureSettings, Settings

pytestmark = pytest.mark.redis
CREATE = {
    "env": "particle",
    "ego_goal": "a2",
    "partners": [{"index": 1, "infer": True}, {"index": 2, "goal": "b3"}],
    "seed": 4,
}
OBS = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.0, 0.0, -0.3, 0.2, 0.0, 0.0]
SECRET = "shared-store-secret-" + new_secret().decode()


@pytest.fixture(scope="module")
def engine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        yield InferenceEngine(store)


@pytest.fixture
def url() -> Iterator[str]:
    with redis_url() as url:
        yield url
        from services.sessions.codec import SessionCodec

        drop_namespace(url, SessionCodec(SECRET.encode()).namespace())


def worker(engine: InferenceEngine, store_url: str, secret: str = SECRET) -> TestClient:
    """One worker's app: the routes over the engine, settings as `coexist serve --workers 2`."""
    app = FastAPI()
    app.include_router(router)
    app.include_router(sessions_router)
    install_error_handlers(app)
    app.state.engine = engine
    app.state.settings = Settings(
        dev_mode=True,
        workers=2,
        session_store_url=store_url,
        session_secret=SecretStr(secret),
    )
    return TestClient(app, raise_server_exceptions=False)


def error_of(response: Any, status: int, code: str) -> str:
    assert response.status_code == status, response.text
    assert response.headers["content-type"] == "application/problem+json"
    error = response.json()
    assert error["code"] == code and error["type"] == f"/problems/{code}", error
    return str(error["detail"])


def test_workers_take_turns_on_one_session(engine: InferenceEngine, url: str) -> None:
    one, two = worker(engine, url), worker(engine, url)
    response = one.post("/v1/sessions", json=CREATE)
    assert response.status_code == 201, response.text  # several workers: no refusal
    session_id = response.json()["session_id"]
    steps = []
    for t in range(4):
        body: dict[str, Any] = {"observation": OBS, "expected_step": t}
        if t:
            body["observed"] = [{"index": 1, "action": t % 5}]
        response = (one, two)[t % 2].post(f"/v1/sessions/{session_id}/steps", json=body)
        assert response.status_code == 200, response.text
        steps.append(response.json())
    assert [s["step"] for s in steps] == [0, 1, 2, 3]
    assert steps[-1]["beliefs"][0]["updates"] == 3
    again = one.post(
        f"/v1/sessions/{session_id}/steps", json={"observation": OBS, "expected_step": 3}
    )
    assert "is at step 4, not 3" in error_of(again, 409, "step_conflict")
    info = two.get(f"/v1/sessions/{session_id}").json()
    assert info["step"] == 4 and 0 < info["expires_in_s"] <= 300
    assert one.delete(f"/v1/sessions/{session_id}").status_code == 204
    gone = two.post(f"/v1/sessions/{session_id}/steps", json={"observation": OBS})
    assert "or was deleted" in error_of(gone, 404, "session_not_found")


def test_foreign_tampered_and_silent_stores_are_named(engine: InferenceEngine, url: str) -> None:
    import redis

    from services.sessions.codec import FORMAT, SessionCodec

    here = worker(engine, url)
    other_secret = "another-deployment-" + new_secret().decode()
    foreign = worker(engine, url, other_secret).post("/v1/sessions", json=CREATE)
    try:
        step = here.post(
            f"/v1/sessions/{foreign.json()['session_id']}/steps", json={"observation": OBS}
        )
        assert "did not issue it" in error_of(step, 404, "session_not_found")
    finally:
        drop_namespace(url, SessionCodec(other_secret.encode()).namespace())

    bad, good = (here.post("/v1/sessions", json=CREATE).json()["session_id"] for _ in range(2))
    key = f"coexist:{SessionCodec(SECRET.encode()).namespace()}:s:{bad}"
    with redis.Redis.from_url(url) as client:
        client.hset(key, "r", FORMAT + b"\0" * 40)
        client.hincrby(key, "v", 1)
    step = here.post(f"/v1/sessions/{bad}/steps", json={"observation": OBS})
    assert "integrity check" in error_of(step, 410, "session_state_invalid")
    assert here.post(f"/v1/sessions/{good}/steps", json={"observation": OBS}).status_code == 200

    silent = worker(engine, f"redis://:pa55word-not-shown@127.0.0.1:{free_port()}/0")
    for response in (
        silent.post("/v1/sessions", json=CREATE),
        silent.post(f"/v1/sessions/{good}/steps", json={"observation": OBS}),
        silent.get(f"/v1/sessions/{good}"),
    ):
        message = error_of(response, 503, "session_store_unavailable")
        assert "did not answer" in message and "pa55word" not in message
        assert SECRET not in response.text
    # the store answers again for the worker that reaches it: the session went on untouched
    step = here.post(f"/v1/sessions/{good}/steps", json={"observation": OBS, "expected_step": 1})
    assert step.status_code == 200, step.text


def test_a_shared_store_needs_a_secret() -> None:
    settings = Settings(dev_mode=True, session_store_url="redis://127.0.0.1:6379/0")
    with pytest.raises(InsecureSettings, match="COEXIST_SESSION_SECRET is unset"):
        settings.check_secure()
    weak = Settings(
        admin_token=SecretStr("a-strong-admin-token-0123456789"),
        session_store_url="redis://127.0.0.1:6379/0",
        session_secret=SecretStr("short"),
    )
    with pytest.raises(InsecureSettings, match="COEXIST_SESSION_SECRET has 5 characters") as err:
        weak.check_secure()
    assert "short'" not in str(err.value)
    assert "short" not in repr(weak.session_secret)
