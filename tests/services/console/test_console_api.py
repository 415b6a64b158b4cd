"""The console's server side without a browser: the live episode (lanes, common random numbers,
`coexist run`'s episode reproduced, beliefs, the NDJSON stream, errors naming the field), the
registry overview, the page's files, the read token, and its routes after every API route."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import orjson
import pytest
from coexist_client import CoexistClient
from console_zoo import build_console_zoo
from fastapi.testclient import TestClient
from http_live_server import inference_app, live_http_server
from pydantic import SecretStr

from model_store.sql import SqlModelStore
from services.app import create_app
from services.console import STATIC_DIR, is_public
from services.console.episodes import EpisodeSettings, LiveEpisode
from services.engine import InferenceEngine
from services.env_client import run_episodes
from services.settings import Settings

ADMIN, READ = "console-admin-t0ken", "console-read-t0ken"
EPISODE = "/v1/console/episode"


@pytest.fixture(scope="module")
def zoo_url(tmp_path_factory: pytest.TempPathFactory) -> str:
    return build_console_zoo(tmp_path_factory.mktemp("console_zoo") / "models.db")


@pytest.fixture(scope="module")
def engine(zoo_url: str) -> Iterator[InferenceEngine]:
    with SqlModelStore(zoo_url) as store:
        yield InferenceEngine(store)


def _client(zoo_url: str, tmp_path: Path, **settings: Any) -> TestClient:
    config = Settings(
        admin_token=SecretStr(ADMIN),
        data_dir=tmp_path,
        store_url=zoo_url,
        grpc_enabled=False,
        **settings,
    )
    return TestClient(create_app(config))


@pytest.fixture(scope="module")
def client(zoo_url: str, tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with _client(zoo_url, tmp_path_factory.mktemp("console_app")) as test_client:
        yield test_client


def _play(engine: InferenceEngine, **fields: Any) -> list[dict[str, Any]]:
    return list(LiveEpisode(engine, EpisodeSettings(**fields)).frames())


def _positions(frames: list[dict[str, Any]], lane: int) -> list[list[tuple[float, float]]]:
    out = []
    for frame in frames:
        if frame["type"] == "frame" and frame["lanes"][lane] is not None:
            out.append([(a["x"], a["y"]) for a in frame["lanes"][lane]["agents"]])
    return out


def test_lanes_start_alike_and_differ_by_policy_only(engine: InferenceEngine) -> None:
    common = dict(env="particle", ego_goal="a2", partner_goals=("b3",), seed=5, max_steps=40)
    both = _play(engine, methods=("sl", "aail"), **common)
    sl_alone = _play(engine, methods=("sl",), **common)
    aail_alone = _play(engine, methods=("aail",), **common)
    # common random numbers: a lane is the same episode whatever lanes run beside it
    assert _positions(both, 0) == _positions(sl_alone, 0)
    assert _positions(both, 1) == _positions(aail_alone, 0)
    sl, aail = _positions(both, 0), _positions(both, 1)
    assert sl[0] == aail[0]  # the same start
    assert sl != aail  # a non-aligned pair: the impact network changes what the ego does
    assert both[-1]["type"] == "end"
    assert [lane["method"] for lane in both[-1]["lanes"]] == ["sl", "aail"]


def test_a_particle_lane_is_coexist_runs_first_episode(engine: InferenceEngine) -> None:
    frames = _play(
        engine,
        env="particle",
        ego_goal="a2",
        partner_goals=("b3", "c"),
        methods=("aail",),
        seed=9,
        max_steps=30,
    )
    summary = frames[-1]["lanes"][0]
    with live_http_server(inference_app(engine)) as url, CoexistClient(url) as sdk:
        (run,) = run_episodes(
            sdk,
            ego_goal="a2",
            partner_goals=["b3", "c"],
            method="aail",
            episodes=1,
            seed=9,
            max_steps=30,
        )
    assert summary["length"] == run.length
    assert summary["returns"] == pytest.approx(list(run.returns), abs=1e-9)


def test_frames_carry_distributions_weights_and_returns(engine: InferenceEngine) -> None:
    frames = _play(
        engine,
        env="particle",
        ego_goal="a2",
        partner_goals=("b3",),
        inferred=(1,),
        methods=("aail",),
        seed=1,
        max_steps=12,
    )
    steps = [f for f in frames if f["type"] == "frame"]
    assert [f["t"] for f in steps] == list(range(len(steps)))
    running = 0.0
    for t, frame in enumerate(steps):
        lane = frame["lanes"][0]
        running += lane["rewards"][0]
        assert lane["returns"][0] == pytest.approx(running)
        if lane["done"]:
            assert "policies" not in lane and t == len(steps) - 1
            continue
        for policy in lane["policies"]:
            assert sum(policy["probs"]) == pytest.approx(1.0, abs=1e-9)
            assert 0 <= policy["action"] < 5
        ego = lane["ego"]
        assert 0.0 <= ego["task_weight"] <= 1.0 and [
            w["index"] for w in ego["partner_weights"]
        ] == [1]
        (belief,) = ego["beliefs"]
        assert belief["index"] == 1 and belief["updates"] == t  # one observed action per step
        assert len(belief["top"]) == 3 and sum(g["prob"] for g in belief["top"]) <= 1.0 + 1e-9
    assert steps[0]["lanes"][0]["rewards"] == [0.0, 0.0]
    assert "models" in steps[0]["lanes"][0]["ego"] and "models" not in steps[1]["lanes"][0]["ego"]


def _lines(response: Any) -> list[dict[str, Any]]:
    return [orjson.loads(line) for line in response.text.splitlines()]


def test_the_stream_is_a_header_then_steps_then_an_end(client: TestClient) -> None:
    query = "env=cooking&ego_goal=TomatoLettuceSalad&partners=CarrotBanana&methods=sl&max_steps=5"
    response = client.get(f"{EPISODE}?{query}")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("application/x-ndjson")
    lines = _lines(response)
    header, frames, end = lines[0], lines[1:-1], lines[-1]
    assert header["type"] == "episode" and header["settings"]["partners"] == ["CarrotBanana"]
    assert [a["role"] for a in header["agents"]] == ["ego", "partner"]
    assert header["action_meanings"] == ["stay", "up", "down", "left", "right"]
    assert header["scene"]["width"] == 11 and header["scene"]["height"] == 5
    assert len(frames) == 6 and end == {"type": "end", "lanes": [end["lanes"][0]]}
    assert end["lanes"][0]["length"] == 5 and frames[-1]["lanes"][0]["done"]
    assert len(frames[0]["lanes"][0]["shapes"]) > 0  # the kitchen's objects


@pytest.mark.parametrize(
    ("query", "status", "field"),
    [
        ("env=nowhere&ego_goal=a2", 422, "env"),
        ("env=particle&ego_goal=zz", 422, "ego_goal"),
        ("env=particle&ego_goal=a2&partners=b3,zz", 422, "partners"),
        ("env=particle&ego_goal=a2&partners=a0,a1,a2,a3,a4", 422, "partners"),
        ("env=cooking&ego_goal=OnionSoup&partners=OnionSoup,OnionSoup", 422, "partners"),
        ("env=particle&ego_goal=a2&partners=b3&infer=2", 422, "infer"),
        ("env=particle&ego_goal=a2&partners=b3&infer=one", 422, "infer"),
        ("env=particle&ego_goal=a2&methods=sl,sl", 422, "methods"),
        ("env=particle&ego_goal=a2&methods=best", 422, "methods"),
        ("env=particle&ego_goal=a2&methods=", 422, "methods"),
        ("env=particle&ego_goal=a2&seed=-1", 422, "seed"),
        ("env=particle&ego_goal=a2&max_steps=0", 422, "max_steps"),
        ("env=particle&ego_goal=a2&max_steps=1001", 422, "max_steps"),
        ("env=particle&ego_goal=a2&temperature=0", 422, "temperature"),
        ("env=particle&ego_goal=a2&alias=NOT%20AN%20ALIAS", 422, "alias"),
        ("env=particle&ego_goal=a2&partners=b3&methods=jl", 404, "methods"),
        ("env=particle&ego_goal=a2&alias=nobody", 404, None),
        ("ego_goal=a2", 422, "env"),
    ],
)
def test_bad_settings_are_a_4xx_naming_the_field(
    client: TestClient, query: str, status: int, field: str | None
) -> None:
    response = client.get(f"{EPISODE}?{query}")
    assert response.status_code == status, response.text
    error = response.json()
    assert error["detail"]
    if field is not None:
        assert error["field"] == field, error


def test_a_partner_without_a_task_network_is_blamed_on_partners(
    zoo_url: str, tmp_path: Path
) -> None:
    """The ego's networks are there, the partner's own task network is not (its alias)."""
    copy = tmp_path / "models.db"
    copy.write_bytes(Path(zoo_url.removeprefix("sqlite:///")).read_bytes())
    with SqlModelStore(f"sqlite:///{copy}") as store:
        store.delete_alias("particle/task/c1", "production")
    with _client(f"sqlite:///{copy}", tmp_path) as guarded:
        answer = guarded.get(f"{EPISODE}?env=particle&ego_goal=a2&partners=c1&methods=sl")
    assert answer.status_code == 404
    assert answer.json()["field"] == "partners" and "c1" in answer.json()["detail"]


def test_the_overview_lists_every_model_with_its_versions(client: TestClient) -> None:
    body = client.get("/v1/console/models").json()
    registry = client.get("/v1/registry/models", params={"page_size": 1000}).json()["models"]
    assert [m["name"] for m in body["models"]] == [m["name"] for m in registry]
    a2 = next(m for m in body["models"] if m["name"] == "particle/task/a2")
    assert [v["version"] for v in a2["versions"]] == [2, 1]
    assert a2["aliases"] == {"candidate": 2, "latest": 2, "production": 1}
    events = client.get("/v1/registry/events", params={"limit": 1000}).json()
    assert body["last_event_id"] == events["last_id"]
    assert [e["id"] for e in body["recent_events"]] == [e["id"] for e in events["events"][-20:]]
    kitchen = client.get("/v1/console/models", params={"env": "cooking", "kind": "task"}).json()
    assert len(kitchen["models"]) == 5 and not kitchen["truncated"]


def test_the_page_and_every_module_it_imports_are_served(client: TestClient) -> None:
    root = client.get("/", follow_redirects=False)
    assert root.status_code == 307 and root.headers["location"] == "/console/"
    page = client.get("/console/")
    assert (
        page.status_code == 200 and "script-src 'self'" in page.headers["content-security-policy"]
    )
    assert '<script type="module" src="/console/static/js/main.js">' in page.text
    for path in sorted(STATIC_DIR.rglob("*.js")):
        served = client.get(f"/console/static/{path.relative_to(STATIC_DIR)}")
        assert served.status_code == 200 and "javascript" in served.headers["content-type"]
        for module in re.findall(r'from "\./([\w.]+)"', path.read_text()):
            assert (path.parent / module).is_file(), f"{path.name} imports a missing {module}"


def test_reads_follow_the_read_token(zoo_url: str, tmp_path: Path) -> None:
    with _client(zoo_url, tmp_path, read_token=SecretStr(READ)) as guarded:
        query = f"{EPISODE}?env=particle&ego_goal=a2&max_steps=2"
        for path in (query, "/v1/console/models"):
            assert guarded.get(path).status_code == 401
            assert guarded.get(path, headers={"Authorization": "Bearer nope"}).status_code == 403
            for token in (READ, ADMIN):
                answer = guarded.get(path, headers={"Authorization": f"Bearer {token}"})
                assert answer.status_code == 200
        # the page and its files hold no data, and a browser loads them without a token
        for path in ("/", "/console/", "/console/static/js/main.js", "/console/static/console.css"):
            assert is_public(path) and guarded.get(path).status_code in (200, 307), path
        assert not is_public("/v1/console/models") and not is_public("/console/../v1/envs")
        assert not is_public("/console/static/../../v1/envs")


def _paths(routes: list[Any]) -> Iterator[str]:
    """Route paths in matching order (an included router's routes where it was included)."""
    for route in routes:
        inner = getattr(route, "original_router", None)
        if inner is not None:
            yield from _paths(inner.routes)
        else:
            yield getattr(route, "path", "")


def test_console_routes_come_after_every_api_route(client: TestClient) -> None:
    """An API request is matched before any console route is tried: the console adds nothing to
    the path of `/v1/act` (no middleware either: the app's stack is what it was)."""
    paths = list(_paths(client.app.routes))  # type: ignore[attr-defined]
    first_console = min(i for i, p in enumerate(paths) if p == "/" or "console" in p)
    for api in ("/v1/act", "/v1/act:batch", "/v1/envs", "/healthz", "/readyz", "/metrics"):
        assert paths.index(api) < first_console
    assert all(p == "/" or "console" in p for p in paths[first_console:])


def _explained_by_the_page(status: int, body: Any) -> dict[str, Any]:
    """What the page's `api.js` makes of an error answer (`fromBody`), run by Node."""
    node = shutil.which("node")
    if node is None:
        pytest.skip("no Node.js to run the page's api.js")
    script = (
        f"import {{fromBody}} from {json.dumps((STATIC_DIR / 'js' / 'api.js').as_uri())};\n"
        f"const e = fromBody({status}, 'Status text', {json.dumps(body)});\n"
        "console.log(JSON.stringify({code: e.code, message: e.message, field: e.field, "
        "explained: e.explain()}));\n"
    )
    out = subprocess.run(
        [node, "--input-type=module", "-e", script], capture_output=True, text=True, check=True
    )
    explained: dict[str, Any] = json.loads(out.stdout)
    return explained


def test_the_page_reads_problem_details_and_the_older_shape(client: TestClient) -> None:
    answer = client.get(f"{EPISODE}?ego_goal=a2")  # no env
    assert (
        answer.status_code == 422 and answer.headers["content-type"] == "application/problem+json"
    )
    problem = answer.json()
    seen = _explained_by_the_page(answer.status_code, problem)
    assert seen["code"] == problem["code"] and seen["field"] == problem["field"]
    assert seen["message"] == problem["detail"]
    assert seen["explained"] == f"Error 422 [{problem['field']}]: {problem['detail']}"
    older = {"error": {"code": "invalid_request", "message": "ego_goal: no", "field": "ego_goal"}}
    seen = _explained_by_the_page(422, older)
    assert (seen["code"], seen["message"], seen["field"]) == (
        "invalid_request",
        "ego_goal: no",
        "ego_goal",
    )
    anonymous = _explained_by_the_page(401, {"type": "/problems/unauthorized", "status": 401})
    assert anonymous["explained"].startswith("Refused (401)")
    proxy_page = _explained_by_the_page(502, None)
    assert (proxy_page["code"], proxy_page["message"]) == ("http_error", "Status text")
