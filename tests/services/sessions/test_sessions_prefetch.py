"""Scoring ahead (`Session.prepare_next`): a step whose evidence was scored right after the
previous answer gives the numbers of a step that scores it on demand, bit for bit, for one,
three and four inferred partners, any subset and order the table can serve; otherwise (another
order of a batched table, an alias moved, new settings) the pass runs again. The transports call
it after each answer: REST as a background task, gRPC `Episode` after the yield."""

from __future__ import annotations

import shutil
import threading
import time
from collections.abc import Iterator

import httpx
import numpy as np
import pytest
import uvicorn
from fastapi import FastAPI
from fastapi.testclient import TestClient
from grpc_live_server import live_grpc_server
from session_zoo import LAYER_SCALES, random_observation, session_zoo_template

import services.sessions.session as session_module
from model_store.entities import Lineage
from model_store.naming import task_model_name
from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_tensors
from policy.belief import BeliefConfig
from services.app import create_app
from services.engine import InferenceEngine, ModelNotFound
from services.engine.goal_inference import ROWS_INDEPENDENT
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.rest import install_error_handlers, sessions_router
from services.sessions import Observed, Session, SessionPartner, SessionSettings, SessionStore
from services.settings import Settings

MOVED_GOAL = "c1"  # its task network gets a version 2 (the reload test)


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SqlModelStore]:
    """A copy of the session zoo with a version 2 of one task network (production stays 1)."""
    path = tmp_path_factory.mktemp("prefetch") / "models.db"
    shutil.copy(session_zoo_template(tmp_path_factory), path)
    with SqlModelStore(f"sqlite:///{path}") as opened:
        spec = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
        tensors = qnet_tensors(spec, seed=4242)
        for k, scale in enumerate(LAYER_SCALES):
            tensors[f"layers.{k}.weight"] *= scale
        import safetensors.numpy

        opened.register_version(
            task_model_name("particle", MOVED_GOAL),
            spec=spec,
            weights=safetensors.numpy.save(tensors),
            lineage=Lineage(config={"alpha": 0.05}, seed=4242, registered_by="pytest"),
        )
        yield opened


@pytest.fixture(scope="module")
def engine(store: SqlModelStore) -> InferenceEngine:
    return InferenceEngine(store)


def settings(n_agents: int, **kwargs: object) -> SessionSettings:
    partners = tuple(SessionPartner(i, infer=True) for i in range(1, n_agents))
    return SessionSettings("particle", "a2", partners, seed=3, **kwargs)  # type: ignore[arg-type]


def assert_same_step(got: object, want: object) -> None:
    """Two `SessionStepResult`s equal to the bit (floats compared with ==)."""
    assert got == want


def observed_of(rng: np.random.Generator, indices: list[int]) -> list[Observed]:
    return [Observed(i, int(rng.integers(5))) for i in indices]


@pytest.mark.parametrize(
    ("n_agents", "orders"),
    [
        (2, [[1]]),
        # rows of a table of <= 3 partners are independent: any subset, any order
        (4, [[1, 2, 3], [3, 1], [2], [1, 2, 3], [2, 3, 1]]),
        # a batched table (4 partners) serves its own order only; the others run the pass
        (5, [[1, 2, 3, 4], [1, 2, 3, 4], [4, 3, 2, 1], [2, 4], [1, 2, 3, 4]]),
    ],
)
def test_a_step_scored_ahead_is_the_step_scored_on_demand(
    engine: InferenceEngine, n_agents: int, orders: list[list[int]]
) -> None:
    ahead = Session(engine, settings(n_agents))
    on_demand = Session(engine, settings(n_agents), prefetch=False)
    rng = np.random.default_rng(n_agents)
    obs = random_observation(rng, n_agents)
    assert_same_step(ahead.step(obs), on_demand.step(obs))
    used = 0
    for t, order in enumerate(orders * 2, start=1):
        assert ahead.prepare_next() is True
        assert on_demand.prepare_next() is False  # prefetch off
        before = engine.stats.likelihood_tables_used
        obs = random_observation(rng, n_agents)
        observed = observed_of(rng, order)
        got = ahead.step(obs, observed)
        assert_same_step(got, on_demand.step(obs, observed))
        served = engine.stats.likelihood_tables_used - before
        previous = (orders * 2)[t - 2] if t > 1 else list(range(1, n_agents))
        # the table is made for the partners the last step observed, in its order; its rows
        # are independent with the compiled forward
        servable = order == previous or (ROWS_INDEPENDENT and set(order) <= set(previous))
        assert served == int(servable), (t, order, previous)
        used += served
    assert used > 0


@pytest.mark.parametrize("n_agents", [2, 4])
def test_a_noisy_likelihood_scored_ahead_is_the_one_scored_on_demand(
    engine: InferenceEngine, n_agents: int
) -> None:
    # the table holds the mixed likelihood of every action: picking from it is the pass's bits
    belief = BeliefConfig(noise=0.2)
    ahead = Session(engine, settings(n_agents, belief=belief))
    on_demand = Session(engine, settings(n_agents, belief=belief), prefetch=False)
    plain = Session(engine, settings(n_agents, belief=BeliefConfig(noise=0.0)), prefetch=False)
    rng = np.random.default_rng(10 + n_agents)
    obs = random_observation(rng, n_agents)
    for session in (ahead, on_demand, plain):
        session.step(obs)
    partners = list(range(1, n_agents))
    for _ in range(4):
        assert ahead.prepare_next() is True
        before = engine.stats.likelihood_tables_used
        obs, observed = random_observation(rng, n_agents), observed_of(rng, partners)
        got = ahead.step(obs, observed)
        assert engine.stats.likelihood_tables_used == before + 1
        assert_same_step(got, on_demand.step(obs, observed))
        assert got.beliefs != plain.step(obs, observed).beliefs  # the noise is applied


def test_a_step_without_evidence_prepares_nothing_after_the_first(
    engine: InferenceEngine,
) -> None:
    session = Session(engine, settings(2))
    rng = np.random.default_rng(0)
    session.step(random_observation(rng))
    assert session.prepare_next() is True  # step 1 will likely bring the partner's action
    assert session.prepare_next() is False  # made already
    session.step(random_observation(rng))  # ... it did not
    assert session.prepare_next() is False
    session.step(random_observation(rng), [Observed(1, 2)])
    assert session.prepare_next() is True


def test_an_alias_moved_after_the_table_was_made_is_scored_with_the_new_networks(
    engine: InferenceEngine, store: SqlModelStore
) -> None:
    name = task_model_name("particle", MOVED_GOAL)
    ahead = Session(engine, settings(2))
    rng = np.random.default_rng(11)
    first, second = random_observation(rng), random_observation(rng)
    ahead.step(first)
    assert ahead.prepare_next() is True
    store.set_alias(name, "production", 2)
    try:
        assert engine.refresh() is True
        before = engine.stats.likelihood_tables_used
        got = ahead.step(second, [Observed(1, 4)])
        assert engine.stats.likelihood_tables_used == before  # the table was stale
        on_demand = Session(engine, settings(2), prefetch=False)
        on_demand.step(first)
        assert_same_step(got, on_demand.step(second, [Observed(1, 4)]))
        stale = Session(engine, settings(2), prefetch=False)
    finally:
        store.set_alias(name, "production", 1)
        engine.refresh()
    stale.step(first)  # production is version 1 again: the old networks' numbers differ
    assert stale.step(second, [Observed(1, 4)]).beliefs != got.beliefs


def test_new_settings_drop_the_table(engine: InferenceEngine) -> None:
    ahead = Session(engine, settings(2))
    on_demand = Session(engine, settings(2), prefetch=False)
    rng = np.random.default_rng(5)
    obs = random_observation(rng)
    ahead.step(obs)
    on_demand.step(obs)
    assert ahead.prepare_next() is True
    hotter = settings(2, belief=BeliefConfig(temperature=0.5))
    ahead.replace_settings(hotter)
    on_demand.replace_settings(hotter)
    assert ahead.prepare_next() is False  # no partner is expected until a step brings one
    obs = random_observation(rng)
    assert_same_step(ahead.step(obs, [Observed(1, 1)]), on_demand.step(obs, [Observed(1, 1)]))


def test_a_failing_table_is_left_to_the_step(
    engine: InferenceEngine, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`prepare_next` never raises for the engine's errors: the step runs the pass and reports
    them itself."""

    def missing(*args: object, **kwargs: object) -> object:
        raise ModelNotFound("particle/task/c1", "production", field="partners")

    session = Session(engine, settings(2))
    session.step(random_observation(np.random.default_rng(1)))
    monkeypatch.setattr(session_module, "likelihood_table", missing)
    assert session.prepare_next() is False


def rest_client(engine: InferenceEngine, prefetch: bool) -> TestClient:
    app = FastAPI()
    app.include_router(sessions_router)
    install_error_handlers(app)
    app.state.engine = engine
    app.state.settings = Settings(session_prefetch=prefetch)
    return TestClient(app)


@pytest.mark.parametrize("prefetch", [True, False])
def test_rest_steps_score_ahead_after_the_answer(engine: InferenceEngine, prefetch: bool) -> None:
    rng = np.random.default_rng(8)
    with rest_client(engine, prefetch) as client:
        body = {"env": "particle", "ego_goal": "a2", "partners": [{"index": 1, "infer": True}]}
        session_id = client.post("/v1/sessions", json=body).json()["session_id"]
        store: SessionStore = client.app.state.sessions  # type: ignore[attr-defined]
        assert store.prefetch is prefetch
        answers = []
        tables, used = engine.stats.likelihood_tables, engine.stats.likelihood_tables_used
        for t in range(4):
            step = {"observation": random_observation(rng).tolist()}
            if t:
                step["observed"] = [{"index": 1, "action": t}]
            reply = client.post(f"/v1/sessions/{session_id}/steps", json=step)
            assert reply.status_code == 200
            answers.append(reply.json())
    assert engine.stats.likelihood_tables - tables == (4 if prefetch else 0)
    assert engine.stats.likelihood_tables_used - used == (3 if prefetch else 0)
    assert [a["beliefs"][0]["updates"] for a in answers] == [0, 1, 2, 3]


def test_an_episode_scores_ahead_after_each_answer(store: SqlModelStore) -> None:
    rng = np.random.default_rng(6)
    steps = []
    for t in range(5):
        step = pb.EpisodeStep(observation=random_observation(rng).tolist())
        if t == 0:
            step.settings.CopyFrom(
                pb.EpisodeSettings(
                    env="particle",
                    ego_goal="a2",
                    seed=2,
                    partners=[pb.PartnerSpec(index=1, infer=True)],
                )
            )
        else:
            step.observed.add(index=1, action=t % 5)
        steps.append(step)
    answers = {}
    for prefetch in (True, False):
        with live_grpc_server(store, session_prefetch=prefetch) as live:
            answers[prefetch] = list(live.stub.Episode(iter(steps)))
            stats = live.engine.stats
            assert stats.likelihood_tables_used == (4 if prefetch else 0)
            assert stats.likelihood_passes == (0 if prefetch else 4)
    assert answers[True] == answers[False]


def test_the_answer_is_sent_before_the_table_is_made(
    store: SqlModelStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Over a real socket (the whole app, its middlewares included): `prepare_next` runs only
    once the client holds the step's answer. The patched `prepare_next` waits until the client
    says it has the answer; run before the answer was sent it would time out."""
    answered, order = threading.Event(), []

    def after_the_answer(self: Session) -> bool:
        order.append(answered.wait(timeout=10))
        return True

    monkeypatch.setattr(Session, "prepare_next", after_the_answer)
    app = create_app(Settings(grpc_enabled=False, dev_mode=True), store)
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=0, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        while not server.started:
            time.sleep(0.01)
        port = server.servers[0].sockets[0].getsockname()[1]
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as client:
            body = {"env": "particle", "ego_goal": "a2", "partners": [{"index": 1, "infer": True}]}
            session_id = client.post("/v1/sessions", json=body).json()["session_id"]
            rng = np.random.default_rng(3)
            for _ in range(2):
                answered.clear()
                step = {"observation": random_observation(rng).tolist()}
                reply = client.post(f"/v1/sessions/{session_id}/steps", json=step)
                assert reply.status_code == 200
                answered.set()
    finally:
        server.should_exit = True
        thread.join(timeout=10)
    assert order == [True, True]
