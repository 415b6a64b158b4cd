"""A session step's shortcuts give what the plain paths give: an observation as a list of floats
(one pass) = as an array (`check_observations`), errors included; a step without evidence reuses
the last belief's views; the REST answer (models written once per set of networks) = the answer
written field by field from the session core's result."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from session_zoo import random_observation, session_zoo_template

from envs.particle import ACTION_MEANINGS
from model_store.sql import SqlModelStore
from services.engine import InferenceEngine, InvalidRequest
from services.rest import install_error_handlers, router, sessions_router
from services.sessions import Observed, Session, SessionPartner, SessionSettings

FLOAT32_MAX = float(np.finfo(np.float32).max)
MODEL_FIELDS = ("role", "name", "version", "sha256", "partner_index", "goal")  # ModelUsedOut


@pytest.fixture(scope="module")
def engine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InferenceEngine]:
    with SqlModelStore(f"sqlite:///{session_zoo_template(tmp_path_factory)}") as store:
        yield InferenceEngine(store)


def settings(**kwargs: Any) -> SessionSettings:
    return SessionSettings("particle", "a2", (SessionPartner(1, infer=True),), seed=3, **kwargs)


def test_a_list_of_floats_steps_as_the_same_array(engine: InferenceEngine) -> None:
    as_list, as_array = Session(engine, settings()), Session(engine, settings())
    rng = np.random.default_rng(0)
    for t in range(6):
        obs = random_observation(rng)
        observed = [Observed(1, t % 5)] if t else []
        a = as_list.step(obs.tolist(), observed)
        b = as_array.step(obs, observed)
        assert (a.result, a.beliefs) == (b.result, b.beliefs)


def _checked(session: Session, observation: object) -> tuple[Any, ...]:
    """What the step's observation check makes of it: the array and agent count, or the error."""
    try:
        obs, n_agents = session._observation(observation)
    except InvalidRequest as err:
        return err.field, str(err)
    return obs.dtype, obs.tolist(), n_agents


@pytest.mark.parametrize(
    "observation",
    [
        [0.25, -1.0, 3.0, 0.0, 1e-3, 2.0, 1.0, 0.5],
        [FLOAT32_MAX, -FLOAT32_MAX] + [0.1] * 6,  # the largest values float32 holds
        [0.1] * 7 + [1 / 3],  # rounded to float32
        [0, 1, 0, 0, 1, 0, 0, 0],  # ints
        [0.1] * 11 + [True],
        [0.1] * 7 + [float("nan")],
        [0.1] * 7 + [float("inf")],
        [0.1] * 7 + [1e39],  # finite, but not in float32
        [0.1] * 7,  # a length no agent count has
        [0.1] * 7 + ["x"],
    ],
)
def test_a_list_is_checked_as_the_array_is(engine: InferenceEngine, observation: list) -> None:
    session = Session(engine, settings())
    got = _checked(session, observation)
    assert got == _checked(session, np.asarray(observation, dtype=object))
    bad = any(not isinstance(v, int | float) or not abs(v) <= FLOAT32_MAX for v in observation)
    assert (got[0] == "observation") == (bad or len(observation) == 7)


def test_steps_without_evidence_keep_the_belief_and_its_views(engine: InferenceEngine) -> None:
    session, rng = Session(engine, settings()), np.random.default_rng(1)
    session.step(random_observation(rng))
    evidence = session.step(random_observation(rng), [Observed(1, 2)])
    quiet = session.step(random_observation(rng))
    assert [b.top for b in quiet.beliefs] == [b.top for b in evidence.beliefs]
    assert [b.observed_action for b in quiet.beliefs] == [None]
    assert session.snapshot()[1] == quiet.beliefs
    # new blend settings: the views are computed again (one goal blended now)
    session.replace_settings(settings(blend_max_goals=1))
    narrow = session.step(random_observation(rng))
    assert sum(m.role == "impact" for m in narrow.result.models) == 1
    # the same belief: the same goals in the same order, their probabilities to rounding (with
    # numpy 2.4.6 the last bit of one differed: exact float equality was never the claim)
    narrow_top, quiet_top = narrow.beliefs[0].top, quiet.beliefs[0].top
    assert [goal for goal, _ in narrow_top] == [goal for goal, _ in quiet_top]
    assert [p for _, p in narrow_top] == pytest.approx([p for _, p in quiet_top], rel=1e-12)


def _written(settings: SessionSettings, answer: Any) -> dict[str, Any]:
    """The REST answer field by field: /v1/act's, then the session's step and beliefs."""
    result = answer.result
    return {
        "probs": result.probs,
        "action": result.action,
        "greedy_action": result.greedy_action,
        "action_meaning": ACTION_MEANINGS[result.action],
        "method": result.method,
        "diagnostics": {
            "task_entropy": result.task_entropy,
            "task_weight": result.task_weight,
            "partner_weights": [
                {"index": p.index, "weight": w}
                for p, w in zip(settings.partners, result.partner_weights, strict=True)
            ],
        },
        "models": [{field: getattr(m, field) for field in MODEL_FIELDS} for m in result.models],
        "session_id": answer.session_id,
        "step": answer.step,
        "beliefs": [
            {
                "index": b.index,
                "top": [{"goal": g, "prob": p} for g, p in b.top],
                "entropy": b.entropy,
                "observed_action": b.observed_action,
                "updates": b.updates,
            }
            for b in answer.beliefs
        ],
    }


def test_rest_answers_are_the_core_written_out(engine: InferenceEngine) -> None:
    """Two sessions whose blends use other networks, stepped in turn: each answer lists its
    own models (the written models are kept per set of networks)."""
    app = FastAPI()
    app.include_router(router)
    app.include_router(sessions_router)
    install_error_handlers(app)
    app.state.engine = engine
    blends: tuple[dict[str, Any], ...] = ({}, {"blend_max_goals": 2})
    with TestClient(app) as client:
        ids = []
        for belief in blends:
            body = {
                "env": "particle",
                "ego_goal": "a2",
                "partners": [{"index": 1, "infer": True}],
                "seed": 3,
                "belief": belief,
            }
            ids.append(client.post("/v1/sessions", json=body).json()["session_id"])
        cores = [
            Session(engine, settings(**belief), sid)
            for belief, sid in zip(blends, ids, strict=True)
        ]
        rng = np.random.default_rng(2)
        impact: dict[str, set[int]] = {sid: set() for sid in ids}
        for t in range(5):
            obs = random_observation(rng)
            observed = [{"index": 1, "action": (3 * t) % 5}] if t else []
            for sid, core in zip(ids, cores, strict=True):
                got = client.post(
                    f"/v1/sessions/{sid}/steps",
                    json={"observation": obs.tolist(), "observed": observed},
                ).json()
                want = core.step(obs, [Observed(o["index"], o["action"]) for o in observed])
                assert got == _written(core.settings, want)
                impact[sid].add(sum(m["role"] == "impact" for m in got["models"]))
    assert impact == {ids[0]: {35}, ids[1]: {2}}
