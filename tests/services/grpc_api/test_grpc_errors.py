"""Bad input over gRPC: INVALID_ARGUMENT / NOT_FOUND naming the field (in the details message and
the `coexist-field` trailing metadata), INTERNAL for bugs without taking the server down."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import grpc
import pytest
from grpc_live_server import MAX_BATCH, LiveServer, live_grpc_server

from model_store.sql import SqlModelStore
from services.engine import ActRequest, ActResult
from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

OBS_2 = [0.1, 0.4, 0.0, 0.0, 0.7, 0.6, 0.1, -0.1]
NAN, INF = float("nan"), float("inf")
INVALID, NOT_FOUND = grpc.StatusCode.INVALID_ARGUMENT, grpc.StatusCode.NOT_FOUND


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory, _tiny_zoo_template: Any) -> Iterator[LiveServer]:
    # One server for the module: these tests only read (the template store is never written).
    with SqlModelStore(f"sqlite:///{_tiny_zoo_template}") as store, live_grpc_server(store) as live:
        yield live


def field_of(err: grpc.RpcError) -> str | None:
    return dict(err.trailing_metadata() or ()).get("coexist-field")


def act(**changes: Any) -> pb.ActRequest:
    fields: dict[str, Any] = {
        "env": "particle",
        "ego_goal": "a2",
        "observation": OBS_2,
        "partners": [pb.PartnerSpec(index=1, goal="b3")],
    }
    fields.update(changes)
    return pb.ActRequest(**fields)


def state(*rows: list[float]) -> pb.State:
    return pb.State(agents=[pb.Vector(values=r) for r in rows])


ACT_CASES = [
    ("short observation", act(observation=OBS_2[:7]), INVALID, "observation"),
    ("empty observation", act(observation=[]), INVALID, "observation"),
    ("NaN", act(observation=[NAN, *OBS_2[1:]]), INVALID, "observation"),
    ("inf", act(observation=[*OBS_2[:7], INF]), INVALID, "observation"),
    ("beyond float32", act(observation=[1e300, *OBS_2[1:]]), INVALID, "observation"),
    ("unknown env", act(env="chess"), INVALID, "env"),
    ("unknown ego goal", act(ego_goal="z9"), INVALID, "ego_goal"),
    ("unknown method", act(method="magic"), INVALID, "method"),
    (
        "unknown partner goal",
        act(partners=[pb.PartnerSpec(index=1, goal="z9")]),
        INVALID,
        "partners[0].goal",
    ),
    (
        "partner out of range",
        act(partners=[pb.PartnerSpec(index=2, goal="b3")]),
        INVALID,
        "partners[0].index",
    ),
    (
        "partner index 0",
        act(partners=[pb.PartnerSpec(index=0, goal="b3")]),
        INVALID,
        "partners[0].index",
    ),
    ("partner without goal", act(partners=[pb.PartnerSpec(index=1)]), INVALID, "partners[0].goal"),
    (
        "probs not summing to 1",
        act(partners=[pb.PartnerSpec(index=1, goal_probs={"b3": 0.5, "c": 0.4})]),
        INVALID,
        "partners[0].goal_probs",
    ),
    (
        "negative probability",
        act(partners=[pb.PartnerSpec(index=1, goal_probs={"b3": 1.5, "c": -0.5})]),
        INVALID,
        "partners[0].goal_probs",
    ),
    ("negative temperature", act(temperature=-0.1), INVALID, "temperature"),
    ("zero temperature", act(temperature=0.0), INVALID, "temperature"),
    ("NaN temperature", act(temperature=NAN), INVALID, "temperature"),
    (
        "negative regret bound",
        act(method="aail_bounded", regret_bound=-0.1),
        INVALID,
        "regret_bound",
    ),
    ("NaN regret bound", act(regret_bound=NAN), INVALID, "regret_bound"),
    ("regret bound with nail", act(method="nail", regret_bound=0.1), INVALID, "regret_bound"),
    ("negative seed", act(seed=-1), INVALID, "seed"),
    ("bad alias", act(alias="no spaces allowed"), INVALID, "alias"),
    ("version 0", act(versions={"particle/task/a2": 0}), INVALID, "versions[particle/task/a2]"),
    ("observation and state", act(state=state([0.1, 0.2, 0, 0])), INVALID, "observation"),
    (
        "state row too short",
        act(observation=[], state=state([0.1, 0.2, 0]), ego_index=0),
        INVALID,
        "state",
    ),
    (
        "state with NaN",
        act(observation=[], state=state([0.1, 0.2, 0, 0], [NAN, 0, 0, 0])),
        INVALID,
        "state",
    ),
    (
        "ego index out of range",
        act(observation=[], state=state([0.1, 0.2, 0, 0]), ego_index=3),
        INVALID,
        "ego_index",
    ),
    ("no task model", act(ego_goal="e4"), NOT_FOUND, "ego_goal"),
    (
        "no impact model",
        act(partners=[pb.PartnerSpec(index=1, goal="e4")]),
        NOT_FOUND,
        "partners[0].goal",
    ),
    (
        "pinned version missing",
        act(versions={"particle/task/a2": 9}),
        NOT_FOUND,
        "versions[particle/task/a2]",
    ),
    ("alias missing", act(alias="staging"), NOT_FOUND, "ego_goal"),
    (
        "no joint model",
        act(method="jl", partners=[pb.PartnerSpec(index=1, goal="c")]),
        NOT_FOUND,
        "method",
    ),
]


@pytest.mark.parametrize(
    ("request_", "code", "field"), [c[1:] for c in ACT_CASES], ids=[c[0] for c in ACT_CASES]
)
def test_act_errors_name_the_field(
    live: LiveServer, request_: pb.ActRequest, code: grpc.StatusCode, field: str
) -> None:
    with pytest.raises(grpc.RpcError) as info:
        live.stub.Act(request_)
    assert info.value.code() == code
    assert field_of(info.value) == field
    assert info.value.details().startswith(f"{field}: ")


def batch(**changes: Any) -> pb.ActBatchRequest:
    fields: dict[str, Any] = {
        "env": "particle",
        "ego_goal": "a2",
        "observations": [pb.Vector(values=OBS_2)] * 4,
        "partners": [pb.PartnerSpec(index=1, goal="b3")],
    }
    fields.update(changes)
    return pb.ActBatchRequest(**fields)


BATCH_CASES = [
    ("oversized", batch(observations=[pb.Vector(values=OBS_2)] * (MAX_BATCH + 1)), "observations"),
    ("empty", batch(observations=[]), "observations"),
    (
        "ragged rows",
        batch(observations=[pb.Vector(values=OBS_2), pb.Vector(values=OBS_2[:4])]),
        "observations",
    ),
    (
        "NaN in row 2",
        batch(observations=[pb.Vector(values=OBS_2)] * 2 + [pb.Vector(values=[NAN] * 8)]),
        "observations[2]",
    ),
    (
        "NaN in state 1",
        batch(
            observations=[],
            states=[
                state([0.1, 0.2, 0, 0], [0.3, 0.4, 0, 0]),
                state([0.1, 0.2, 0, 0], [0.3, INF, 0, 0]),
            ],
        ),
        "states[1]",
    ),
    ("states and observations", batch(states=[state([0.1, 0.2, 0, 0])]), "observations"),
]


@pytest.mark.parametrize(
    ("request_", "field"), [c[1:] for c in BATCH_CASES], ids=[c[0] for c in BATCH_CASES]
)
def test_act_batch_errors_name_the_field(
    live: LiveServer, request_: pb.ActBatchRequest, field: str
) -> None:
    with pytest.raises(grpc.RpcError) as info:
        live.stub.ActBatch(request_)
    assert info.value.code() == INVALID
    assert field_of(info.value) == field


@pytest.mark.parametrize("method", ["Act", "ActBatch"])
def test_malformed_protobuf_is_invalid_argument(live: LiveServer, method: str) -> None:
    raw = live.channel.unary_unary(f"/coexist.v1.PolicyService/{method}")  # bytes in, bytes out
    with pytest.raises(grpc.RpcError) as info:
        raw(b"\x0a\xff\xff\xff\xff\x0f")  # field 1 claims a length far past the end
    assert info.value.code() == INVALID
    assert field_of(info.value) == "request"
    assert live.stub.Act(act()).method == "aail_bounded"  # still serving


def test_episode_errors_name_the_step(live: LiveServer) -> None:
    settings = pb.EpisodeSettings(env="particle", ego_goal="a2")
    with pytest.raises(grpc.RpcError) as info:
        list(live.stub.Episode(iter([pb.EpisodeStep(observation=OBS_2)])))
    assert info.value.code() == INVALID and field_of(info.value) == "settings"
    assert info.value.details().startswith("step[0]: settings: ")

    steps = [
        pb.EpisodeStep(settings=settings, observation=OBS_2),
        pb.EpisodeStep(observation=OBS_2),
        pb.EpisodeStep(observation=OBS_2[:5]),
    ]
    responses = live.stub.Episode(iter(steps))
    assert next(responses).method == "aail_bounded" and next(responses).method == "aail_bounded"
    with pytest.raises(grpc.RpcError) as info:
        next(responses)
    assert info.value.code() == INVALID and field_of(info.value) == "observation"
    assert info.value.details().startswith("step[2]: observation: ")

    missing = pb.EpisodeSettings(env="particle", ego_goal="e4")
    with pytest.raises(grpc.RpcError) as info:
        list(live.stub.Episode(iter([pb.EpisodeStep(settings=missing, observation=OBS_2)])))
    assert info.value.code() == NOT_FOUND and field_of(info.value) == "ego_goal"


def test_unexpected_error_is_internal_and_the_server_keeps_serving(
    live: LiveServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    real_act = live.engine.act
    calls = []

    def broken_once(request: ActRequest) -> list[ActResult]:
        calls.append(request)
        if len(calls) == 1:
            raise RuntimeError("a bug")
        return real_act(request)

    monkeypatch.setattr(live.engine, "act", broken_once)
    with pytest.raises(grpc.RpcError) as info:
        live.stub.Act(act())
    assert info.value.code() == grpc.StatusCode.INTERNAL
    assert "a bug" not in info.value.details()  # no internals leak
    assert live.stub.Act(act()).method == "aail_bounded"
