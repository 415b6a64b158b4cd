"""benchmarks/alternative_servers.py, alternatives_bench.py and capacity.py's anchor: the
alternatives' numpy AAIL is coexist's (the engine's probabilities and seeded actions,
`policy.blend`'s reference blend), the hand-written grpcio server answers the benchmark's gRPC
act with them, the plain app's numpy sessions answer as a coexist `Session` step after step,
and, marked slow, the FastAPI alternative answers the benchmark's act over a socket."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import alternative_servers  # noqa: E402
import alternatives_bench  # noqa: E402
import capacity  # noqa: E402
import serving  # noqa: E402
import session_scene  # noqa: E402


@pytest.fixture(scope="module")
def store_url(tmp_path_factory: pytest.TempPathFactory) -> str:
    url = f"sqlite:///{tmp_path_factory.mktemp('alternatives') / 'models.db'}"
    serving.build_store(url)
    return url


def _act_body() -> dict:
    body: dict = json.loads(serving.rest_bodies()["act"])
    return body


def _engine_results(url: str, body: dict, seeds: list[int]) -> list:
    from model_store import open_store
    from services.engine.engine import InferenceEngine
    from services.engine.messages import ActRequest, PartnerSpec

    partners = tuple(PartnerSpec(p["index"], goal=p["goal"]) for p in body["partners"])
    obs = np.array([body["observation"]])
    with open_store(url) as store:
        engine = InferenceEngine(store)
        return [
            engine.act(ActRequest("particle", body["ego_goal"], obs, partners, "aail", seed=seed))[
                0
            ]
            for seed in seeds
        ]


def test_numpy_aail_gives_the_engines_probs_and_seeded_actions(store_url: str) -> None:
    body = _act_body()
    assert body["method"] == "aail" and len(body["partners"]) == 4
    policy = alternative_servers.NumpyAAIL(store_url)
    assert sorted(policy.networks) == [
        "particle/impact/a0",
        "particle/impact/b2",
        "particle/impact/c4",
        "particle/impact/e1",
        "particle/task/a2",
    ]
    partners = [(p["index"], p["goal"]) for p in body["partners"]]
    probs = policy.probs(body["ego_goal"], body["observation"], partners)
    seeds = list(range(20))
    results = _engine_results(store_url, body, seeds)
    np.testing.assert_allclose(probs, results[0].probs, rtol=0, atol=1e-5)
    # a seed draws the same uniform, so the same action wherever the probs agree this well
    assert [policy.sample(probs, s) for s in seeds] == [r.action for r in results]


def test_the_aail_blend_is_policy_blends_reference() -> None:
    from policy.blend import blend_vectorised

    rng = np.random.default_rng(3)
    cases = [(rng.normal(size=5), rng.normal(size=(p, 5))) for p in (0, 1, 4)]
    flat = np.full(5, 2.0)
    cases += [(flat, rng.normal(size=(2, 5))), (rng.normal(size=5), np.stack([flat, flat]))]
    for q_task, q_impact in cases:
        for alpha in (0.02, 0.5):
            ours = alternative_servers.aail(q_task, q_impact, alpha)
            reference = blend_vectorised("aail", q_task[None], q_impact[None], alpha).probs_BA[0]
            np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-9)


def test_different_probs_stop_the_benchmark() -> None:
    reference = np.array([0.5, 0.25, 0.25])
    alternatives_bench.check_same_probs("fastapi", reference + 4e-6, reference)
    with pytest.raises(SystemExit, match="not the same maths"):
        alternatives_bench.check_same_probs(
            "fastapi", reference + np.array([2e-5, -2e-5, 0]), reference
        )
    with pytest.raises(SystemExit, match="not the same maths"):
        alternatives_bench.check_same_probs("ray", reference[:2], reference)


def test_the_tables_show_medians_and_ratios_to_coexist() -> None:
    def case(name: str, requests: int, p50: float) -> serving.Case:
        return serving.Case("REST", name, 1, requests, 1.0, p50, 1, 0)

    def server(scale: float) -> dict[str, serving.Case]:
        return {
            "no-op c=1": case("no-op c=1", 10000, 0.1),
            "act c=1": case("act c=1", round(5000 / scale), 0.2 * scale),
            "act c=32": case("act c=32", round(8000 / scale), 4.0 * scale),
        }

    def grpc(scale: float) -> dict[str, serving.Case]:
        return {
            "grpc act c=1": case("grpc act c=1", round(4000 / scale), 0.25 * scale),
            "grpc act c=32": case("grpc act c=32", round(9000 / scale), 3.5 * scale),
        }

    rounds = [
        {"coexist": server(1.0) | grpc(1.0), "fastapi": server(s), "grpcio": grpc(s)}
        for s in (2.0, 3.0, 2.5)
    ]
    figures = alternatives_bench.medians(rounds)
    assert figures["fastapi"]["act_p50_ms"] == pytest.approx(0.5)
    assert figures["fastapi"]["act_rps_c32"] == 3200
    assert figures["grpcio"]["grpc_act_rps_c32"] == 3600
    assert "act_p50_ms" not in figures["grpcio"] and "grpc_act_p50_ms" not in figures["fastapi"]
    text = alternatives_bench.tables(figures)

    def rows(label: str) -> list[list[str]]:
        return [
            [cell.strip() for cell in line.strip("|").split("|")]
            for line in text.splitlines()
            if line.startswith(f"| {label} |")
        ]

    # the medians of the synthetic rounds above, then their ratios to coexist's
    fastapi = rows(alternatives_bench.LABELS["fastapi"])
    assert fastapi[0][1:] == [f"{0.1:.3f} ms", "10,000", f"{0.5:.3f} ms", "2,000", "3,200"]
    assert fastapi[1][1:] == ["2.50x", "0.40x", "0.40x"]
    assert rows(alternatives_bench.LABELS["grpcio"])[0][1:] == [f"{0.625:.3f} ms", "1,600", "3,600"]
    # coexist's gRPC p50 0.25 over its REST p50 0.2; its c = 32 rate 9,000 over grpcio's 3,600
    targets = {name: (ratio, met) for name, ratio, _, met in alternatives_bench.targets(figures)}
    assert targets == {
        "coexist: gRPC act p50 / REST act p50 (c=1, the same request)": (1.25, False),
        "coexist gRPC act req/s / grpcio + numpy's (c=32)": (2.5, True),
    }


def test_the_grpcio_alternative_answers_coexists_act(store_url: str) -> None:
    import grpc

    from services.grpc_api.gen.coexist.v1 import policy_pb2 as pb

    server, port = alternative_servers.grpcio_server(store_url, 0)
    server.start()
    try:
        probs = alternatives_bench.grpc_act_probs(port)
        request = pb.ActRequest.FromString(serving.grpc_bodies()["act"][5:])
        request.seed = 7
        with grpc.insecure_channel(f"127.0.0.1:{port}") as channel:
            act = channel.unary_unary(
                serving.ACT,
                request_serializer=pb.ActRequest.SerializeToString,
                response_deserializer=pb.ActResponse.FromString,
            )
            seeded = act(request, timeout=10)
            codes = []
            for change in ({"method": "aail_bounded"}, {"ego_goal": "zz"}):
                bad = pb.ActRequest()
                bad.CopyFrom(request)
                for field, value in change.items():
                    setattr(bad, field, value)
                with pytest.raises(grpc.RpcError) as failed:
                    act(bad, timeout=10)
                codes.append(failed.value.code())
    finally:
        server.stop(grace=None)
    (result,) = _engine_results(store_url, _act_body(), [7])
    alternatives_bench.check_same_probs("grpcio", probs, np.asarray(result.probs))
    np.testing.assert_allclose(seeded.probs, result.probs, rtol=0, atol=1e-5)
    assert seeded.action == result.action and seeded.method == "aail"
    assert codes == [grpc.StatusCode.INVALID_ARGUMENT, grpc.StatusCode.NOT_FOUND]


@pytest.fixture(scope="module")
def scene_url(tmp_path_factory: pytest.TempPathFactory) -> str:
    """Every particle network (the capacity benchmark's store): sessions weigh every goal."""
    url = f"sqlite:///{tmp_path_factory.mktemp('scene') / 'models.db'}"
    session_scene.build_store(url)
    return url


def test_the_plain_sessions_answer_as_a_coexist_session(scene_url: str) -> None:
    from fastapi.testclient import TestClient

    create = {**capacity.CREATE, "method": "aail"}
    bodies = capacity.check_bodies(12)
    reference = capacity.coexist_session_answers(scene_url, create, bodies)
    with TestClient(alternative_servers.plain_app(scene_url)) as client:
        answers = capacity.http_session_answers(client, create, bodies)
        created = client.post("/v1/sessions", json=create).json()["session_id"]
        json_type = {"content-type": "application/json"}
        late = client.post(f"/v1/sessions/{created}/steps", content=bodies[1], headers=json_type)
        unknown = client.post("/v1/sessions/nope/steps", content=bodies[0], headers=json_type)
        announced = {**create, "partners": [{"index": 1, "infer": False}]}
        refused = client.post("/v1/sessions", json=announced)
    capacity.check_same_answers("numpy sessions", answers, reference)
    # the beliefs moved: the later steps' probabilities are not the first step's
    assert max(float(np.abs(p - reference[0][0]).max()) for p, _ in reference[1:]) > 1e-3
    assert late.status_code == 422 and "step 0" in late.json()["detail"]
    assert unknown.status_code == 404
    assert refused.status_code == 422 and "infer" in refused.json()["detail"]


def test_different_session_answers_stop_the_capacity_run() -> None:
    reference = [(np.array([0.5, 0.5]), 1), (np.array([0.25, 0.75]), 0)]
    capacity.check_same_answers("ray", [(p + 4e-6, a) for p, a in reference], reference)
    with pytest.raises(SystemExit, match=r"step 1 .*not the same maths"):
        capacity.check_same_answers("ray", [reference[0], (reference[1][0], 1)], reference)
    with pytest.raises(SystemExit, match=r"step 0 .*not the same maths"):
        capacity.check_same_answers("ray", [(reference[0][0] + 2e-5, 1), reference[1]], reference)


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("taskset") is None, reason="taskset not installed")
def test_the_fastapi_alternative_answers_the_act(store_url: str, tmp_path: Path) -> None:
    import httpx

    port = alternatives_bench.free_port()
    server = alternatives_bench.start_alternative("fastapi", port, store_url, tmp_path / "log")
    try:
        probs = alternatives_bench.act_probs(port)
        body = {**_act_body(), "seed": 7}
        seeded = httpx.post(f"http://127.0.0.1:{port}/v1/act", json=body, timeout=10).json()
        missing = {**body, "ego_goal": "zz"}
        assert httpx.post(f"http://127.0.0.1:{port}/v1/act", json=missing).status_code == 404
    finally:
        alternatives_bench.stop_alternative(server)
    assert server.returncode is not None
    assert alternatives_bench.session_members(server.pid) == []
    (result,) = _engine_results(store_url, body, [7])
    alternatives_bench.check_same_probs("fastapi", probs, np.asarray(result.probs))
    assert seeded["action"] == result.action
