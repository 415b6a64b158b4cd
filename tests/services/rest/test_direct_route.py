"""`DirectJson` (services/rest/direct_route.py): a valid JSON body for a given route reaches the
endpoint without FastAPI's router and dependency solving, and everything else answers exactly as
FastAPI does; routes with dependencies and endpoints of another shape are not given; endpoint
errors go to the app's exception handlers; only FastAPI's and Starlette's public names are used."""

from __future__ import annotations

import ast
import pathlib
from collections.abc import Iterator
from typing import Annotated, Any

import fastapi.routing
import orjson
import pytest
from fastapi import APIRouter, Body, Depends, FastAPI, HTTPException, Path, Request, Response
from fastapi.testclient import TestClient

from services.rest import direct_route, install_error_handlers, router, sessions_router
from services.rest.direct_route import DirectJson, direct_call, direct_routes
from services.rest.json_body import FastJsonRoute
from services.rest.session_schemas import SessionStepBody


async def echo(item_id: str, body: SessionStepBody, request: Request) -> Response:
    answer = {"item_id": item_id, "body": body.model_dump(), "request": type(request).__name__}
    return Response(orjson.dumps(answer), media_type="application/json")


def _app(endpoint: Any = echo, *, direct: bool = True, **route: Any) -> FastAPI:
    items = APIRouter(prefix="/v1", route_class=FastJsonRoute)
    items.add_api_route("/items/{item_id}/steps", endpoint, methods=["POST"], **route)
    app = FastAPI()
    app.include_router(items)
    install_error_handlers(app)
    if direct:
        app.add_middleware(DirectJson, routes=direct_routes(items))
    return app


def _client(**kwargs: Any) -> TestClient:
    return TestClient(_app(**kwargs))


@pytest.fixture(scope="module")
def clients() -> Iterator[tuple[TestClient, TestClient]]:
    with _client() as lean, _client(direct=False) as full:
        yield lean, full


JSON = {"content-type": "application/json"}
REQUESTS: list[tuple[bytes, dict[str, str]]] = [
    (b'{"observation": [0.1, 2, -3.5], "observed": [{"index": 1, "action": 3}]}', JSON),
    (b'{"state": [[0, 1], [2, 3]], "ego_index": 0, "expected_step": 4}', JSON),
    (b'{"observation": [1.0]}', {"content-type": "application/json; charset=utf-8"}),
    (b'{"observation": [1.0]}', {"content-type": "text/plain"}),
    (b'{"observation": [1.0]}', {}),
    (b"", JSON),
    (b'{"observation": [1.0', JSON),
    (b'{"observation": [NaN]}', JSON),
    (b'{"expected_step": 18446744073709551616}', JSON),
    (b'{"observation": [true]}', JSON),
    (b'{"observed": [{"index": "1"}]}', JSON),
    (b'{"observation": [1.0], "extra": 1}', JSON),
    (b"[1, 2]", JSON),
    (b"null", JSON),
    (b'{"observation": "\xff"}', JSON),
]


@pytest.mark.parametrize(("content", "headers"), REQUESTS)
def test_both_paths_answer_alike(
    clients: tuple[TestClient, TestClient], content: bytes, headers: dict[str, str]
) -> None:
    lean, full = clients
    got = lean.post("/v1/items/a%2Fb/steps", content=content, headers=headers)
    expected = full.post("/v1/items/a%2Fb/steps", content=content, headers=headers)
    assert (got.status_code, got.content) == (expected.status_code, expected.content)


def test_a_valid_body_skips_dependency_solving(
    clients: tuple[TestClient, TestClient], monkeypatch: pytest.MonkeyPatch
) -> None:
    solved: list[object] = []
    solve = fastapi.routing.solve_dependencies

    async def spy(*args: Any, **kwargs: Any) -> Any:
        solved.append(kwargs.get("body"))
        return await solve(*args, **kwargs)

    monkeypatch.setattr(fastapi.routing, "solve_dependencies", spy)
    lean, full = clients
    valid, invalid = b'{"observation": [1.0]}', b'{"observation": ["x"]}'
    assert lean.post("/v1/items/x/steps", content=valid, headers=JSON).status_code == 200
    assert solved == []  # straight to the endpoint
    assert lean.post("/v1/items/x/steps", content=invalid, headers=JSON).status_code == 422
    assert full.post("/v1/items/x/steps", content=valid, headers=JSON).status_code == 200
    assert len(solved) == 2  # FastAPI's handler for the invalid body and for FastJsonRoute


def test_a_route_with_a_dependency_is_not_given() -> None:
    def deny() -> None:
        raise HTTPException(403, "no")

    guarded = APIRouter(prefix="/v1", dependencies=[Depends(deny)])
    guarded.add_api_route("/items/{item_id}/steps", echo, methods=["POST"])
    assert direct_routes(guarded) == ()
    with _client(dependencies=[Depends(deny)]) as client:
        response = client.post("/v1/items/x/steps", content=b'{"observation": [1]}', headers=JSON)
    assert response.status_code == 403


def test_no_private_fastapi_or_starlette_names_are_read() -> None:
    tree = ast.parse(pathlib.Path(direct_route.__file__).read_text())
    imported = [
        (node.module, alias.name)
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom)
        and (node.module or "").startswith(("fastapi", "starlette"))
        for alias in node.names
    ]
    assert imported
    assert not [(m, n) for m, n in imported if n.startswith("_") or "._" in f".{m}"]
    own = {  # the middleware's own attributes and methods
        *(
            n.attr
            for n in ast.walk(tree)
            if isinstance(n, ast.Attribute) and isinstance(n.ctx, ast.Store)
        ),
        *(n.name for n in ast.walk(tree) if isinstance(n, ast.AsyncFunctionDef | ast.FunctionDef)),
    }
    read = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    assert not [a for a in read - own if a.startswith("_")]


def _route(endpoint: Any, **kwargs: Any) -> fastapi.routing.APIRoute:
    things = APIRouter(route_class=FastJsonRoute)
    things.add_api_route("/things/{item_id}", endpoint, methods=["POST"], **kwargs)
    route = things.routes[0]
    assert isinstance(route, fastapi.routing.APIRoute)
    return route


async def with_query(item_id: str, body: SessionStepBody, request: Request, q: int) -> None: ...
async def with_constraint(
    item_id: Annotated[str, Path(max_length=3)], body: SessionStepBody, request: Request
) -> None: ...
async def embedded(
    item_id: str, body: Annotated[SessionStepBody, Body(embed=True)], request: Request
) -> None: ...
async def without_request(item_id: str, body: SessionStepBody) -> None: ...
def synchronous(item_id: str, body: SessionStepBody, request: Request) -> None: ...


@pytest.mark.parametrize(
    "endpoint", [with_query, with_constraint, embedded, without_request, synchronous]
)
def test_other_endpoints_take_fastapis_handler(endpoint: Any) -> None:
    assert direct_call(_route(endpoint)) is None


def test_a_route_with_a_dependency_takes_fastapis_handler() -> None:
    assert direct_call(_route(echo, dependencies=[Depends(lambda: None)])) is None
    assert direct_call(_route(echo)) is not None


def test_the_act_and_session_posts_are_direct() -> None:
    paths = {direct.route.path for direct in direct_routes(router, sessions_router)}
    assert paths == {"/v1/act", "/v1/act:batch", "/v1/sessions/{session_id}/steps", "/v1/sessions"}


async def fails(item_id: str, body: SessionStepBody, request: Request) -> Response:
    if item_id == "http":
        raise HTTPException(409, "taken")
    if item_id == "engine":
        from services.engine import InvalidRequest

        raise InvalidRequest("observation", "not today")
    raise RuntimeError("unexpected")


@pytest.mark.parametrize("item_id", ["http", "engine"])
def test_endpoint_errors_are_the_apps_exception_handlers(item_id: str) -> None:
    answers = []
    for direct in (True, False):
        with TestClient(_app(fails, direct=direct)) as client:
            response = client.post(
                f"/v1/items/{item_id}/steps", content=b'{"observation": [1]}', headers=JSON
            )
        answers.append((response.status_code, response.content))
    assert answers[0] == answers[1] and answers[0][0] in (409, 422)


def test_an_unhandled_endpoint_error_propagates() -> None:
    with (
        TestClient(_app(fails), raise_server_exceptions=True) as client,
        pytest.raises(RuntimeError),
    ):
        client.post("/v1/items/x/steps", content=b'{"observation": [1]}', headers=JSON)


def test_the_access_log_and_metrics_see_the_route_template(
    clients: tuple[TestClient, TestClient],
) -> None:
    from services.logging import route_template

    seen: list[str | None] = []

    async def spy(item_id: str, body: SessionStepBody, request: Request) -> Response:
        seen.append(route_template(dict(request.scope)))
        return Response(b"{}", media_type="application/json")

    for direct in (True, False):
        with TestClient(_app(spy, direct=direct)) as client:
            client.post("/v1/items/x/steps", content=b'{"observation": [1]}', headers=JSON)
    assert seen == ["/v1/items/{item_id}/steps"] * 2


def test_a_body_in_chunks_is_read_whole(clients: tuple[TestClient, TestClient]) -> None:
    lean, full = clients

    def chunks() -> Iterator[bytes]:
        yield b'{"observation": [0.5,'
        yield b" 1.5]}"

    got = lean.post("/v1/items/x/steps", content=chunks(), headers=JSON)
    expected = full.post("/v1/items/x/steps", content=b'{"observation": [0.5, 1.5]}', headers=JSON)
    assert got.status_code == 200 and got.content == expected.content


@pytest.mark.parametrize("direct", [True, False])
def test_the_served_app_has_the_direct_path_unless_switched_off(
    direct: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    from services.app import create_app
    from services.settings import Settings

    monkeypatch.setenv("COEXIST_DEV_MODE", "1")
    app = create_app(Settings(direct_json=direct))
    assert (DirectJson in [m.cls for m in app.user_middleware]) is direct
