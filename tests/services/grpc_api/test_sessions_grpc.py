"""The gRPC Episode stream with inferred partners: the same answers and beliefs as a REST session
for the same inputs and seed, settings replaced mid-stream, errors naming the field, and the
session errors' status codes."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import grpc
import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from grpc_live_server import LiveServer, live_grpc_server
from session_zoo import random_observation, session_zoo_template

from envs.particle.world import observations, step_state
from model_store.sql import SqlModelStore
from services.grpc_api.errors import FIELD_METADATA_KEY, status_of
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb
from services.rest import install_error_handlers, sessions_router
from services.sessions import (
    Observed,
    Session,
    SessionLimitReached,
    SessionNotFound,
    SessionPartner,
    SessionSettings,
    StepConflict,
)

OBS_2 = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.1, -0.1]


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveServer]:
    url = f"sqlite:///{session_zoo_template(tmp_path_factory)}"
    with SqlModelStore(url) as store, live_grpc_server(store) as live:
        yield live


@pytest.fixture
def rest(live: LiveServer) -> Iterator[TestClient]:
    app = FastAPI()
    app.include_router(sessions_router)
    install_error_handlers(app)
    app.state.engine = live.engine
    with TestClient(app) as client:
        yield client


def episode_settings(**kwargs: Any) -> pb.EpisodeSettings:
    fields: dict[str, Any] = {"env": "particle", "ego_goal": "a2", "seed": 9}
    fields["partners"] = [
        pb.PartnerSpec(index=1, goal="c1", infer=True),
        pb.PartnerSpec(index=2, goal="b3"),
    ]
    fields.update(kwargs)
    return pb.EpisodeSettings(**fields)


def grpc_error(live: LiveServer, steps: list[pb.EpisodeStep]) -> tuple[Any, str | None]:
    with pytest.raises(grpc.RpcError) as info:
        list(live.stub.Episode(iter(steps)))
    err: Any = info.value
    field = dict(err.trailing_metadata() or ()).get(FIELD_METADATA_KEY)
    return err, field


def test_an_episode_gives_the_answers_and_beliefs_of_a_rest_session(
    live: LiveServer, rest: TestClient
) -> None:
    created = rest.post(
        "/v1/sessions",
        json={
            "env": "particle",
            "ego_goal": "a2",
            "seed": 9,
            "partners": [{"index": 1, "goal": "c1", "infer": True}, {"index": 2, "goal": "b3"}],
            "belief": {
                "forgetting": 0.9,
                "floor": 0.002,
                "noise": 0.15,
                "blend_mass": 0.95,
                "blend_max_goals": 4,
            },
        },
    ).json()
    belief = pb.BeliefSettings(
        forgetting=0.9, floor=0.002, noise=0.15, blend_mass=0.95, blend_max_goals=4
    )
    rng = np.random.default_rng(2)
    obs_TD = [random_observation(rng, n_agents=3) for _ in range(6)]
    actions = [None, 3, 1, 4, 4, 0]
    steps = []
    for t, (obs, action) in enumerate(zip(obs_TD, actions, strict=True)):
        step = pb.EpisodeStep(observation=obs.tolist())
        if t == 0:
            step.settings.CopyFrom(episode_settings(belief=belief))
        else:
            step.observed.add(index=1, action=action)
        steps.append(step)
    answers = list(live.stub.Episode(iter(steps)))
    assert len(answers) == 6
    for t, (obs, action, answer) in enumerate(zip(obs_TD, actions, answers, strict=True)):
        observed = [] if action is None else [{"index": 1, "action": action}]
        body = {"observation": obs.tolist(), "observed": observed}
        want = rest.post(f"/v1/sessions/{created['session_id']}/steps", json=body).json()
        assert want["step"] == t
        assert list(answer.probs) == want["probs"]
        assert (answer.action, answer.greedy_action) == (want["action"], want["greedy_action"])
        weights = [w.weight for w in answer.diagnostics.partner_weights]
        assert weights == [w["weight"] for w in want["diagnostics"]["partner_weights"]]
        assert [m.name for m in answer.models] == [m["name"] for m in want["models"]]
        (belief_out,) = answer.beliefs
        (wanted,) = want["beliefs"]
        assert belief_out.index == 1 and belief_out.updates == wanted["updates"] == t
        assert [(g.goal, g.prob) for g in belief_out.top] == [
            (g["goal"], g["prob"]) for g in wanted["top"]
        ]
        assert belief_out.entropy == wanted["entropy"]
        observed_action = (
            belief_out.observed_action if belief_out.HasField("observed_action") else None
        )
        assert observed_action == wanted["observed_action"] == action


def test_an_episode_recovers_actions_from_states(live: LiveServer) -> None:
    state = np.array([[[0.2, 0.3, 0.0, 0.0], [0.7, 0.6, 0.0, 0.0]]])
    settings = episode_settings(partners=[pb.PartnerSpec(index=1)])  # no goal: inferred
    steps = [
        pb.EpisodeStep(
            settings=settings, state=pb.State(agents=[pb.Vector(values=r) for r in state[0]])
        )
    ]
    for action in (2, 2, 4):
        state = step_state(state, np.array([[0, action]]))
        step = pb.EpisodeStep(observation=observations(state)[0, 0].tolist())
        step.observed.add(index=1)  # action unset: recovered
        steps.append(step)
    answers = list(live.stub.Episode(iter(steps)))
    assert [a.beliefs[0].observed_action for a in answers[1:]] == [2, 2, 4]
    assert not answers[0].beliefs[0].HasField("observed_action")


def test_new_settings_keep_the_belief_and_inference_may_start_mid_stream(live: LiveServer) -> None:
    plain = episode_settings(partners=[pb.PartnerSpec(index=1, goal="c1")])
    inferring = episode_settings(partners=[pb.PartnerSpec(index=1, goal="c1", infer=True)])
    steps = [pb.EpisodeStep(settings=plain, observation=OBS_2)]
    switch = pb.EpisodeStep(settings=inferring, observation=[0.2] * 8)
    switch.observed.add(index=1, action=3)  # judged on step 0's observation
    steps.append(switch)
    new_goal = episode_settings(ego_goal="b3", partners=[pb.PartnerSpec(index=1, infer=True)])
    again = _with_observed(pb.EpisodeStep(settings=new_goal, observation=[0.3] * 8), 1, 1)
    steps.append(again)
    answers = list(live.stub.Episode(iter(steps)))
    assert not answers[0].beliefs
    assert [a.beliefs[0].updates for a in answers[1:]] == [1, 2]
    # the same as a session begun on step 0's observation at step 1
    settings = SessionSettings("particle", "a2", (SessionPartner(1, "c1", infer=True),), seed=9)
    session = Session(live.engine, settings, first_step=1, previous_observation=OBS_2)
    want = session.step([0.2] * 8, [Observed(1, 3)])
    assert list(answers[1].probs) == want.result.probs
    assert [(g.goal, g.prob) for g in answers[1].beliefs[0].top] == list(want.beliefs[0].top)


@pytest.mark.parametrize(
    ("field", "steps"),
    [
        (
            "observed",
            lambda s: [_with_observed(pb.EpisodeStep(settings=s, observation=OBS_2), 1, 0)],
        ),
        (
            "observed[0].index",
            lambda s: [
                pb.EpisodeStep(settings=s, observation=OBS_2),
                _with_observed(pb.EpisodeStep(observation=OBS_2), 2, 0),
            ],
        ),
        (
            "observed[0].action",
            lambda s: [
                pb.EpisodeStep(settings=s, observation=OBS_2),
                _with_observed(pb.EpisodeStep(observation=OBS_2), 1, 7),
            ],
        ),
        ("observation", lambda s: [pb.EpisodeStep(settings=s, observation=OBS_2[:5])]),
        (
            "belief.floor",
            lambda s: [
                pb.EpisodeStep(
                    settings=episode_settings(belief=pb.BeliefSettings(floor=0.5)),
                    observation=OBS_2,
                )
            ],
        ),
        (
            "belief.noise",
            lambda s: [
                pb.EpisodeStep(
                    settings=episode_settings(belief=pb.BeliefSettings(noise=1.0)),
                    observation=OBS_2,
                )
            ],
        ),
        (
            "partners[0].infer",
            lambda s: [pb.EpisodeStep(settings=episode_settings(method="jl"), observation=OBS_2)],
        ),
        (
            "belief.prune_below",
            lambda s: [
                pb.EpisodeStep(
                    settings=episode_settings(belief=pb.BeliefSettings(prune_below=-0.1)),
                    observation=OBS_2,
                )
            ],
        ),
        (
            "belief.prune_error",
            lambda s: [
                pb.EpisodeStep(
                    settings=episode_settings(belief=pb.BeliefSettings(prune_error=0.0)),
                    observation=OBS_2,
                )
            ],
        ),
    ],
)
def test_bad_inferring_steps_are_invalid_argument_naming_the_field(
    live: LiveServer, field: str, steps: Any
) -> None:
    settings = episode_settings(partners=[pb.PartnerSpec(index=1, infer=True)])
    err, got_field = grpc_error(live, steps(settings))
    assert err.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert got_field == field
    assert f": {field}:" in err.details()


def _with_observed(step: pb.EpisodeStep, index: int, action: int) -> pb.EpisodeStep:
    step.observed.add(index=index, action=action)
    return step


def test_observed_without_an_inferred_partner_is_refused(live: LiveServer) -> None:
    plain = episode_settings(partners=[pb.PartnerSpec(index=1, goal="c1")])
    second = _with_observed(pb.EpisodeStep(observation=OBS_2), 1, 0)
    err, field = grpc_error(live, [pb.EpisodeStep(settings=plain, observation=OBS_2), second])
    assert err.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert field == "observed[0].index" and "step[1]: " in err.details()


def test_unary_calls_refuse_infer(live: LiveServer) -> None:
    partners = [pb.PartnerSpec(index=1, goal="c1", infer=True)]
    request = pb.ActRequest(env="particle", ego_goal="a2", observation=OBS_2, partners=partners)
    with pytest.raises(grpc.RpcError) as info:
        live.stub.Act(request)
    err: Any = info.value
    assert err.code() == grpc.StatusCode.INVALID_ARGUMENT
    assert dict(err.trailing_metadata())[FIELD_METADATA_KEY] == "partners[0].infer"


def test_session_errors_map_to_their_status_codes() -> None:
    assert status_of(SessionNotFound("abc", "it was deleted"))[0] == grpc.StatusCode.NOT_FOUND
    assert status_of(SessionLimitReached(3))[0] == grpc.StatusCode.RESOURCE_EXHAUSTED
    code, message, field = status_of(StepConflict("abc", 1, 2))
    assert (code, field) == (grpc.StatusCode.ABORTED, "expected_step")
    assert message.startswith("expected_step: session 'abc' is at step 2")
