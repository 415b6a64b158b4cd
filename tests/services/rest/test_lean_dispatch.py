"""`LeanDispatch` (services/rest/lean_route.py): a valid JSON body for a `LeanJsonRoute` reaches
the endpoint without FastAPI's router and dependency solving, and everything else answers
exactly as `FastJsonRoute` does; router-level dependencies always run; only endpoints of the
supported shape qualify; endpoint errors go to the app's exception handlers."""

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

from services.rest import install_error_handlers, lean_route, sessions_router
from services.rest.json_body import FastJsonRoute
from services.rest.lean_route import LeanDispatch, LeanJsonRoute, direct_call
from services.rest.session_schemas import SessionStepBody


async def echo(item_id: str, body: SessionStepBody, request: Request) -> Response:
    answer = {"item_id": item_id, "body": body.model_dump(), "request": type(request).__name__}
    return Response(orjson.dumps(answer), media_type="application/json")


def _client(route_class: type[FastJsonRoute], **include: Any) -> TestClient:
    router = APIRouter(prefix="/v1", route_class=route_class)
    router.add_api_route("/items/{item_id}/steps", echo, methods=["POST"])
    app = FastAPI()
    app.include_router(router, **include)
    install_error_handlers(app)
    app.add_middleware(LeanDispatch)
    return TestClient(app)


@pytest.fixture(scope="module")
def clients() -> Iterator[tuple[TestClient, TestClient]]:
    with _client(LeanJsonRoute) as lean, _client(FastJsonRoute) as full:
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


def test_router_level_dependencies_still_run() -> None:
    def deny() -> None:
        raise HTTPException(403, "no")

    with _client(LeanJsonRoute, dependencies=[Depends(deny)]) as client:
        response = client.post("/v1/items/x/steps", content=b'{"observation": [1]}', headers=JSON)
    assert response.status_code == 403


def test_dependencies_of_an_outer_inclusion_still_run() -> None:
    def deny() -> None:
        raise HTTPException(403, "no")

    inner = APIRouter(prefix="/v1", route_class=LeanJsonRoute)
    inner.add_api_route("/items/{item_id}/steps", echo, methods=["POST"])
    outer = APIRouter(prefix="/outer")
    outer.include_router(inner)
    app = FastAPI()
    app.include_router(outer, dependencies=[Depends(deny)])
    app.include_router(inner)  # the same route included again without: the direct path
    app.add_middleware(LeanDispatch)
    with TestClient(app) as client:
        body = b'{"observation": [1]}'
        guarded = client.post("/outer/v1/items/x/steps", content=body, headers=JSON)
        open_ = client.post("/v1/items/x/steps", content=body, headers=JSON)
    assert guarded.status_code == 403
    assert open_.status_code == 200 and open_.json()["item_id"] == "x"


def test_no_private_fastapi_names_are_read() -> None:
    tree = ast.parse(pathlib.Path(lean_route.__file__).read_text())
    imported = [
        (node.module, alias.name)
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("fastapi")
        for alias in node.names
    ]
    assert imported and not [name for _, name in imported if name.startswith("_")]
    strings = [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant)]
    assert not [v for v in strings if isinstance(v, str) and v.startswith("_effective")]


def _route(endpoint: Any, **kwargs: Any) -> fastapi.routing.APIRoute:
    router = APIRouter(route_class=LeanJsonRoute)
    router.add_api_route("/things/{item_id}", endpoint, methods=["POST"], **kwargs)
    route = router.routes[0]
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


def test_the_session_step_and_create_routes_are_direct() -> None:
    paths = {
        route.path: direct_call(route)
        for route in sessions_router.routes
        if isinstance(route, fastapi.routing.APIRoute) and "POST" in (route.methods or ())
    }
    assert paths.keys() == {"/v1/sessions/{session_id}/steps", "/v1/sessions"}
    assert all(call is not None for call in paths.values())


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
    for route_class in (LeanJsonRoute, FastJsonRoute):
        router = APIRouter(prefix="/v1", route_class=route_class)
        router.add_api_route("/items/{item_id}/steps", fails, methods=["POST"])
        app = FastAPI()
        app.include_router(router)
        install_error_handlers(app)
        app.add_middleware(LeanDispatch)
        with TestClient(app) as client:
            response = client.post(
                f"/v1/items/{item_id}/steps", content=b'{"observation": [1]}', headers=JSON
            )
        answers.append((response.status_code, response.content))
    assert answers[0] == answers[1] and answers[0][0] in (409, 422)


def test_an_unhandled_endpoint_error_propagates() -> None:
    router = APIRouter(prefix="/v1", route_class=LeanJsonRoute)
    router.add_api_route("/items/{item_id}/steps", fails, methods=["POST"])
    app = FastAPI()
    app.include_router(router)
    app.add_middleware(LeanDispatch)
    with TestClient(app, raise_server_exceptions=True) as client, pytest.raises(RuntimeError):
        client.post("/v1/items/x/steps", content=b'{"observation": [1]}', headers=JSON)


def test_an_earlier_route_of_the_same_path_answers() -> None:
    """FastAPI picks the first route that matches in full: the dispatch never jumps it."""

    async def first(item_id: str) -> dict[str, str]:
        return {"first": item_id}

    router = APIRouter(prefix="/v1", route_class=LeanJsonRoute)
    router.add_api_route("/items/{item_id}/steps", echo, methods=["POST"])
    app = FastAPI()
    app.add_api_route("/v1/items/{item_id}/steps", first, methods=["POST"])
    app.include_router(router)
    app.add_middleware(LeanDispatch)
    with TestClient(app) as client:
        response = client.post("/v1/items/x/steps", content=b'{"observation": [1]}', headers=JSON)
    assert response.json() == {"first": "x"}


def test_a_body_in_chunks_is_read_whole(clients: tuple[TestClient, TestClient]) -> None:
    lean, full = clients

    def chunks() -> Iterator[bytes]:
        yield b'{"observation": [0.5,'
        yield b" 1.5]}"

    got = lean.post("/v1/items/x/steps", content=chunks(), headers=JSON)
    expected = full.post("/v1/items/x/steps", content=b'{"observation": [0.5, 1.5]}', headers=JSON)
    assert got.status_code == 200 and got.content == expected.content
