"""The session routes (/v1/sessions) over a particle zoo of random networks: the round trip, the
belief in the answers, expiry, the limit, conflicts, bad steps (422 naming the field, session
unchanged), state input, and the refusal on a server with several workers."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from pydantic import SecretStr
from session_zoo import partner_action, random_observation, session_zoo_template

from envs.particle.world import observations
from model_store.sql import SqlModelStore
from policy.belief import DEFAULT_NOISE, BeliefConfig
from services.app import create_app
from services.engine import InferenceEngine
from services.rest import install_error_handlers, router, sessions_router
from services.sessions import Observed, Session, SessionPartner, SessionSettings, SessionStore
from services.settings import Settings

CREATE = {"env": "particle", "ego_goal": "a2", "partners": [{"index": 1, "infer": True}], "seed": 4}


@pytest.fixture(scope="module")
def engine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        yield InferenceEngine(store)


@pytest.fixture
def app(engine: InferenceEngine) -> FastAPI:
    app = FastAPI()
    app.include_router(router)
    app.include_router(sessions_router)
    install_error_handlers(app)
    app.state.engine = engine
    return app


@pytest.fixture
def client(app: FastAPI) -> Iterator[TestClient]:
    with TestClient(app) as client:
        yield client


class Clock:
    now = 50.0

    def __call__(self) -> float:
        return self.now


def create(client: TestClient, **changes: Any) -> str:
    response = client.post("/v1/sessions", json={**CREATE, **changes})
    assert response.status_code == 201, response.text
    session_id: str = response.json()["session_id"]
    return session_id


def error_of(response: Any, status: int) -> dict[str, Any]:
    assert response.status_code == status, response.text
    error: dict[str, Any] = response.json()
    return error


def test_create_step_get_delete(client: TestClient) -> None:
    response = client.post("/v1/sessions", json=CREATE)
    assert response.status_code == 201
    body = response.json()
    sid = body["session_id"]
    assert response.headers["location"] == f"/v1/sessions/{sid}"
    assert body["step"] == 0 and body["expires_in_s"] == 300.0
    assert body["beliefs"][0]["index"] == 1 and body["beliefs"][0]["updates"] == 0
    assert body["settings"]["partners"] == [
        {"index": 1, "goal": None, "goal_probs": None, "infer": True}
    ]
    assert body["settings"]["belief"]["forgetting"] == 0.95
    assert body["settings"]["belief"]["noise"] == DEFAULT_NOISE
    belief = body["settings"]["belief"]  # the default blend: every goal of the belief
    assert (belief["blend_mass"], belief["blend_max_goals"]) == (1.0, None)

    first = client.post(f"/v1/sessions/{sid}/steps", json={"observation": [0.1] * 8}).json()
    assert first["step"] == 0 and first["session_id"] == sid
    assert sum(m["role"] == "impact" for m in first["models"]) == 35
    assert len(first["probs"]) == 5 and first["action_meaning"]
    assert first["diagnostics"]["partner_weights"][0]["index"] == 1
    second = client.post(
        f"/v1/sessions/{sid}/steps",
        json={
            "observation": [0.2] * 8,
            "observed": [{"index": 1, "action": 2}],
            "expected_step": 1,
        },
    ).json()
    assert second["step"] == 1
    assert second["beliefs"][0]["observed_action"] == 2 and second["beliefs"][0]["updates"] == 1
    got = client.get(f"/v1/sessions/{sid}").json()
    assert got["step"] == 2 and got["beliefs"] == [{**second["beliefs"][0]}]

    assert client.delete(f"/v1/sessions/{sid}").status_code == 204
    error = error_of(client.get(f"/v1/sessions/{sid}"), 404)
    assert error["code"] == "session_not_found" and error["field"] == "session_id"
    assert sid in error["detail"] and "deleted" in error["detail"]
    assert error_of(client.delete(f"/v1/sessions/{sid}"), 404)["code"] == "session_not_found"


@pytest.mark.parametrize("noise", [None, 0.25])
def test_the_answers_equal_the_session_core(
    client: TestClient, engine: InferenceEngine, noise: float | None
) -> None:
    extra = {} if noise is None else {"belief": {"noise": noise}}
    sid = create(
        client,
        partners=[{"index": 1, "goal": "c1", "infer": True}, {"index": 2, "goal": "b3"}],
        **extra,
    )
    belief = BeliefConfig() if noise is None else BeliefConfig(noise=noise)
    assert client.get(f"/v1/sessions/{sid}").json()["settings"]["belief"]["noise"] == belief.noise
    settings = SessionSettings(
        "particle",
        "a2",
        (SessionPartner(1, "c1", infer=True), SessionPartner(2, "b3")),
        seed=4,
        belief=belief,
    )
    core, rng = Session(engine, settings), np.random.default_rng(3)
    for t in range(4):
        obs = random_observation(rng, n_agents=3)
        observed = [{"index": 1, "action": t % 5}] if t else []
        body = {"observation": obs.tolist(), "observed": observed}
        got = client.post(f"/v1/sessions/{sid}/steps", json=body).json()
        want = core.step(obs, [Observed(o["index"], o["action"]) for o in observed])
        assert (got["probs"], got["action"]) == (want.result.probs, want.result.action)
        assert [w["weight"] for w in got["diagnostics"]["partner_weights"]] == (
            want.result.partner_weights
        )
        assert [(g["goal"], g["prob"]) for g in got["beliefs"][0]["top"]] == list(
            want.beliefs[0].top
        )
        assert got["beliefs"][0]["entropy"] == want.beliefs[0].entropy


def test_the_belief_moves_to_the_partners_goal(client: TestClient, engine: InferenceEngine) -> None:
    sid = create(client)
    rng, previous = np.random.default_rng(0), None
    for _ in range(15):
        obs = random_observation(rng)
        observed: list[dict[str, int]] = []
        if previous is not None:
            observed = [{"index": 1, "action": partner_action(engine, previous, 1, "d2")}]
        body = {"observation": obs.tolist(), "observed": observed}
        answer = client.post(f"/v1/sessions/{sid}/steps", json=body).json()
        previous = obs
    top = answer["beliefs"][0]["top"][0]
    assert top["goal"] == "d2" and top["prob"] > 0.5


def test_state_input_equals_the_observation_and_recovers_actions(client: TestClient) -> None:
    by_state, by_obs = create(client), create(client)
    states = [np.array([[0.2, 0.3, 0.0, 0.0], [0.7, 0.6, 0.0, 0.0]])]
    states.append(states[0] + [[0.0, 0.0, 0.0, 0.0], [-0.05, 0.0, -0.05, 0.0]])
    for t, state in enumerate(states):
        observed = [{"index": 1}] if t else []  # action null: recovered from the states
        body = {"state": state.tolist(), "ego_index": 0, "observed": observed}
        a = client.post(f"/v1/sessions/{by_state}/steps", json=body)
        obs = observations(state[None])[0, 0]
        body = {"observation": obs.tolist(), "observed": observed}
        b = client.post(f"/v1/sessions/{by_obs}/steps", json=body)
        assert a.status_code == b.status_code == 200, (a.text, b.text)
        assert {**a.json(), "session_id": ""} == {**b.json(), "session_id": ""}
    assert a.json()["beliefs"][0]["observed_action"] is not None


def test_idle_sessions_expire_with_a_404_that_says_why(app: FastAPI, client: TestClient) -> None:
    clock = Clock()
    app.state.sessions = SessionStore(app.state.engine, ttl_s=10.0, clock=clock)
    sid = create(client)
    clock.now += 9.0
    assert client.get(f"/v1/sessions/{sid}").json()["expires_in_s"] == pytest.approx(1.0)
    clock.now += 1.0
    error = error_of(client.post(f"/v1/sessions/{sid}/steps", json={"observation": [0.0] * 8}), 404)
    assert sid in error["detail"] and "expired after 10 s idle" in error["detail"]


def test_too_many_sessions_is_a_429(app: FastAPI, client: TestClient) -> None:
    app.state.sessions = SessionStore(app.state.engine, max_sessions=1)
    sid = create(client)
    error = error_of(client.post("/v1/sessions", json=CREATE), 429)
    assert error["code"] == "too_many_sessions" and "maximum of 1" in error["detail"]
    client.delete(f"/v1/sessions/{sid}")
    create(client)


def test_a_stale_expected_step_is_a_409(client: TestClient) -> None:
    sid = create(client)
    client.post(f"/v1/sessions/{sid}/steps", json={"observation": [0.0] * 8})
    error = error_of(
        client.post(
            f"/v1/sessions/{sid}/steps", json={"observation": [0.0] * 8, "expected_step": 0}
        ),
        409,
    )
    assert (error["code"], error["field"]) == ("step_conflict", "expected_step")
    assert client.get(f"/v1/sessions/{sid}").json()["step"] == 1


BAD_STEPS = [
    ("observation", {"observation": [0.1] * 7}),
    ("observation", {"observation": [0.1] * 8, "state": [[0.0] * 4] * 2, "ego_index": 0}),
    ("state", {"state": [[0.0] * 4, [0.1] * 3], "ego_index": 0}),
    ("ego_index", {"state": [[0.0] * 4] * 2}),
    ("observed[0].index", {"observed": [{"index": 2, "action": 1}]}),
    ("observed[0].index", {"observed": [{"index": "one", "action": 1}]}),
    ("observed[0].action", {"observed": [{"index": 1, "action": 5}]}),
    ("observed[0].action", {"observed": [{"index": 1, "action": 1.5}]}),
    ("observed[1].index", {"observed": [{"index": 1, "action": 1}, {"index": 1, "action": 2}]}),
    ("observed[0].speed", {"observed": [{"index": 1, "speed": 1}]}),
]


@pytest.mark.parametrize(("field", "body"), BAD_STEPS)
def test_a_bad_step_is_a_422_naming_the_field_and_changes_nothing(
    client: TestClient, field: str, body: dict[str, Any]
) -> None:
    sid = create(client)
    client.post(f"/v1/sessions/{sid}/steps", json={"observation": [0.1] * 8})
    before = client.get(f"/v1/sessions/{sid}").json()
    step = {"observation": [0.2] * 8, "observed": [{"index": 1, "action": 3}], **body}
    if "state" in body:
        del step["observation"]
    if "observation" in body and "state" in body:
        step["observation"] = body["observation"]
    error = error_of(client.post(f"/v1/sessions/{sid}/steps", json=step), 422)
    assert error["field"] == field, error
    after = client.get(f"/v1/sessions/{sid}").json()
    assert (after["step"], after["beliefs"]) == (before["step"], before["beliefs"])


def test_observed_at_step_0_is_a_422(client: TestClient) -> None:
    sid = create(client)
    step = {"observation": [0.2] * 8, "observed": [{"index": 1, "action": 3}]}
    error = error_of(client.post(f"/v1/sessions/{sid}/steps", json=step), 422)
    assert error["field"] == "observed" and "no previous observation" in error["detail"]
    assert client.get(f"/v1/sessions/{sid}").json()["step"] == 0


@pytest.mark.parametrize(
    ("field", "changes"),
    [
        ("belief.forgetting", {"belief": {"forgetting": 0}}),
        ("belief.floor", {"belief": {"floor": 0.2}}),
        ("belief.noise", {"belief": {"noise": 1.0}}),
        ("belief.noise", {"belief": {"noise": -0.1}}),
        ("belief.noise", {"belief": {"noise": "0.1"}}),
        ("belief.blend_mass", {"belief": {"blend_mass": 1.5}}),
        ("belief.blend_max_goals", {"belief": {"blend_max_goals": 0}}),
        ("belief.prune_below", {"belief": {"prune_below": 0.0005}}),  # below the floor
        ("belief.prune_below", {"belief": {"prune_below": 1.5}}),
        ("belief.prune_below", {"belief": {"prune_below": 0.1, "floor": 0.0}}),
        ("belief.prune_error", {"belief": {"prune_error": 0.0}}),
        ("belief.prune_error", {"belief": {"prune_error": 2.0}}),
        ("belief.speed", {"belief": {"speed": 1}}),
        ("partners[0].goal", {"partners": [{"index": 1, "goal": "zz", "infer": True}]}),
        ("partners[0].infer", {"partners": [{"index": 1, "infer": "maybe"}]}),
        ("partners[0].index", {"partners": [{"index": 9, "infer": True}]}),
        ("ego_goal", {"ego_goal": "zz"}),
        ("regret_bound", {"regret_bound": -1.0}),
        ("regret_bound", {"method": "aail", "regret_bound": 0.1}),
    ],
)
def test_bad_settings_are_a_422_naming_the_field(
    client: TestClient, field: str, changes: dict[str, Any]
) -> None:
    error = error_of(client.post("/v1/sessions", json={**CREATE, **changes}), 422)
    assert error["field"] == field, error


def test_unknown_sessions_are_404(client: TestClient) -> None:
    error = error_of(client.post("/v1/sessions/nope/steps", json={"observation": [0.0] * 8}), 404)
    assert "created by another server process" in error["detail"]


def _server_settings(**extra: Any) -> Settings:
    return Settings(admin_token=SecretStr("t0ken-for-the-tests-0123"), grpc_enabled=False, **extra)


def test_the_server_app_keeps_sessions_with_its_settings(tmp_path_factory: Any) -> None:
    url = f"sqlite:///{session_zoo_template(tmp_path_factory)}"
    with SqlModelStore(url) as store:
        settings = _server_settings(session_ttl_s=42.0, max_sessions=3)
        with TestClient(create_app(settings, store=store)) as client:
            assert client.post("/v1/sessions", json=CREATE).json()["expires_in_s"] == 42.0
            assert client.app.state.sessions.max_sessions == 3  # type: ignore[attr-defined]


def test_several_workers_refuse_sessions(tmp_path_factory: Any) -> None:
    url = f"sqlite:///{session_zoo_template(tmp_path_factory)}"
    settings = _server_settings(workers=4)
    with SqlModelStore(url) as store, TestClient(create_app(settings, store=store)) as client:
        error = error_of(client.post("/v1/sessions", json=CREATE), 501)
        assert error["code"] == "sessions_unavailable"
        assert "4 worker processes" in error["detail"]
        assert "Episode" in error["detail"]
        # the stateless routes still answer
        act = {"env": "particle", "ego_goal": "a2", "observation": [0.0] * 8}
        assert client.post("/v1/act", json=act).status_code == 200
