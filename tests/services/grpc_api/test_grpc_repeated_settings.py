"""services.grpc_api.repeated: settings converted once per distinct settings, answer heads kept
per request shape, and never a remembered value where the call differs."""

from __future__ import annotations

import numpy as np
import pytest

from services.engine import ActResult, InvalidRequest, ModelUsed
from services.grpc_api import convert, repeated
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb


def _message(observation: list[float], *, goal: str = "b3", seed: int | None = None):
    message = pb.ActRequest(
        env="particle",
        ego_goal="a2",
        observation=observation,
        partners=[pb.PartnerSpec(index=1, goal=goal)],
        method="aail",
    )
    if seed is not None:
        message.seed = seed
    return message


OBS = [0.1, 0.2, 0.0, 0.0, 0.5, 0.6, 0.0, 0.0]


def test_same_settings_share_one_conversion_and_keep_each_calls_fields() -> None:
    first = convert.act_request(_message(OBS, seed=3))
    second = convert.act_request(_message([x + 1 for x in OBS]))
    assert first.partners is second.partners  # converted once
    assert first.seed == 3 and second.seed is None
    np.testing.assert_array_equal(first.observations, [OBS])
    np.testing.assert_array_equal(second.observations, [[x + 1 for x in OBS]])


def test_other_settings_get_their_own_conversion() -> None:
    b3 = convert.act_request(_message(OBS, goal="b3"))
    c0 = convert.act_request(_message(OBS, goal="c0"))
    assert b3.partners[0].goal == "b3" and c0.partners[0].goal == "c0"


def test_a_refused_setting_is_refused_on_every_call() -> None:
    message = _message(OBS)
    message.partners[0].infer = True
    for _ in range(2):
        with pytest.raises(InvalidRequest, match="infer"):
            convert.act_request(message)


def test_episode_steps_offset_the_seed() -> None:
    settings = pb.EpisodeSettings(
        env="particle", ego_goal="a2", partners=[pb.PartnerSpec(index=1, goal="b3")], seed=10
    )
    steps = [convert.episode_request(settings, pb.EpisodeStep(observation=OBS), t) for t in (0, 4)]
    assert [s.seed for s in steps] == [10, 14]
    assert steps[0].partners is steps[1].partners


def _result(version: int) -> ActResult:
    models = [
        ModelUsed("task", "particle-task-a2", version, "ab" * 32, None, "a2"),
        ModelUsed("impact", "particle-impact-b3", version, "cd" * 32, 1, "b3"),
    ]
    return ActResult([0.2] * 5, 1, 2, "aail", 0.5, 0.3, [1.0], models)


def test_answer_heads_follow_the_models_of_the_call() -> None:
    request = convert.act_request(_message(OBS))
    old, new = _result(1), _result(2)  # a hot reload: new model objects, new versions
    assert [m.version for m in convert.act_response(request, old).models] == [1, 1]
    assert [m.version for m in convert.act_response(request, new).models] == [2, 2]
    again = convert.act_response(request, old)
    assert [m.version for m in again.models] == [1, 1] and again.action == 1


def test_a_head_under_a_colliding_key_is_not_used() -> None:
    """Ids can be reused once an object is gone: an entry is used only for its own objects."""
    request = convert.act_request(_message(OBS))
    result = _result(7)
    key = (request.env, result.method, id(request.partners), *map(id, result.models))
    stranger = _result(1)
    repeated._HEADS[key] = repeated.Head(
        request.partners, tuple(stranger.models), b"", [1], ("noop",)
    )
    answer = convert.act_response(request, result)
    assert [m.version for m in answer.models] == [7, 7]
