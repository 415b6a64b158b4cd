"""`services.logging`: JSON lines, request ids in and out and on every line, access lines."""

from __future__ import annotations

import io
import json
import logging
import logging.config
import time
from collections.abc import Iterator

import pytest
from fastapi import APIRouter, FastAPI
from fastapi.responses import StreamingResponse
from fastapi.testclient import TestClient

from services.logging import (
    JsonFormatter,
    RequestIdFilter,
    RequestIdMiddleware,
    TextFormatter,
    log_config,
)

handler_log = logging.getLogger("coexist.test.handler")


def captured_logs() -> Iterator[io.StringIO]:
    """Root logger output, formatted as the server formats it (JSON, request-id filter); a
    fixture here and in test_grpc_request_ids.py."""
    buffer = io.StringIO()
    handler = logging.StreamHandler(buffer)
    handler.addFilter(RequestIdFilter())
    handler.setFormatter(JsonFormatter())
    root = logging.getLogger()
    old_level = root.level
    root.addHandler(handler)
    root.setLevel(logging.DEBUG)
    try:
        yield buffer
    finally:
        root.removeHandler(handler)
        root.setLevel(old_level)


captured = pytest.fixture(captured_logs)


def _records(buffer: io.StringIO) -> list[dict]:
    """The server's lines (the test client's own httpx lines set aside)."""
    lines = [json.loads(line) for line in buffer.getvalue().splitlines()]
    return [rec for rec in lines if rec["logger"].startswith("coexist.")]


@pytest.fixture
def client() -> Iterator[TestClient]:
    inner = APIRouter()

    @inner.get("/items/{item}/-/detail")
    def detail(item: str) -> dict[str, str]:  # sync: runs in the thread pool
        handler_log.warning("looking at %s", item)
        return {"item": item}

    outer = APIRouter(prefix="/v1/things")
    outer.include_router(inner)
    app = FastAPI()
    app.include_router(outer)

    @app.get("/healthz")
    def healthz() -> dict[str, str]:
        return {"status": "ok"}

    app.add_middleware(RequestIdMiddleware)
    with TestClient(app) as test_client:
        yield test_client


def test_a_client_request_id_is_echoed_and_on_every_line(
    client: TestClient, captured: io.StringIO
) -> None:
    resp = client.get("/v1/things/items/x7/-/detail", headers={"X-Request-ID": "req-42.a:b"})
    assert resp.status_code == 200 and resp.headers["x-request-id"] == "req-42.a:b"
    handler_line, access = _records(captured)
    assert handler_line == {
        **handler_line,
        "msg": "looking at x7",
        "level": "WARNING",
        "logger": "coexist.test.handler",
        "request_id": "req-42.a:b",
    }
    assert access["logger"] == "coexist.access" and access["request_id"] == "req-42.a:b"
    assert access["method"] == "GET" and access["status"] == 200
    assert access["route"] == "/v1/things/items/{item}/-/detail"  # with the router's prefix
    assert access["path"] == "/v1/things/items/x7/-/detail"
    assert access["duration_ms"] >= 0 and access["ts"].endswith("Z")
    assert access["msg"].startswith("GET /v1/things/items/x7/-/detail 200 ")


@pytest.mark.parametrize(
    "sent", [None, b"", b"has space", b"x" * 129, "naïve".encode(), b"a\tb", b"{json}"]
)
def test_a_missing_or_unsafe_request_id_is_replaced(
    client: TestClient, captured: io.StringIO, sent: bytes | None
) -> None:
    headers = {} if sent is None else {"X-Request-ID": sent}
    resp = client.get("/v1/things/items/y/-/detail", headers=headers)
    new_id = resp.headers["x-request-id"]
    assert len(new_id) == 32 and int(new_id, 16) >= 0 and new_id != sent
    assert {r["request_id"] for r in _records(captured)} == {new_id}


def test_probes_log_at_debug_and_unknown_routes_have_no_template(
    client: TestClient, captured: io.StringIO
) -> None:
    client.get("/healthz")
    assert client.get("/nope").status_code == 404
    probe, missing = _records(captured)
    assert probe["level"] == "DEBUG" and probe["route"] == "/healthz"
    assert missing["level"] == "INFO" and missing["status"] == 404 and missing["route"] is None


def test_lines_outside_requests_have_a_null_request_id_and_exceptions_a_traceback() -> None:
    record = logging.LogRecord("coexist.x", logging.ERROR, __file__, 1, "boom %d", (3,), None)
    try:
        raise ValueError("bad")
    except ValueError:
        import sys

        record.exc_info = sys.exc_info()
    RequestIdFilter().filter(record)
    data = json.loads(JsonFormatter().format(record))
    assert data["msg"] == "boom 3" and data["request_id"] is None and data["level"] == "ERROR"
    assert "ValueError: bad" in data["exc"]
    text = TextFormatter().format(record)
    assert " ERROR   coexist.x [-] boom 3\n" in text and text.endswith("ValueError: bad")


def test_log_config_is_a_valid_dict_config_and_refuses_bad_values() -> None:
    config = log_config("json", "warning")
    assert config["root"]["level"] == "WARNING"
    assert config["handlers"]["default"]["formatter"] == "json"
    logging.config.DictConfigurator(config)  # builds without error
    with pytest.raises(ValueError, match="log_format"):
        log_config("xml")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="log_level"):
        log_config("text", "loud")


def test_a_streamed_response_is_timed_to_its_last_byte() -> None:
    """A response streamed over 0.3 s counts 0.3 s, not the moment its first chunk left."""
    pause_s, chunks = 0.1, 4
    app = FastAPI()

    @app.get("/stream")
    def stream() -> StreamingResponse:
        def frames() -> Iterator[bytes]:
            for k in range(chunks):
                if k:
                    time.sleep(pause_s)
                yield f"frame {k}\n".encode()

        return StreamingResponse(frames(), media_type="application/x-ndjson")

    seen: list[tuple[str, str, int, float]] = []
    app.add_middleware(RequestIdMiddleware, record=lambda *row: seen.append(row))
    with TestClient(app) as client:
        assert client.get("/stream").text.count("frame") == chunks
    ((route, method, status, seconds),) = seen
    assert (route, method, status) == ("/stream", "GET", 200)
    assert seconds >= pause_s * (chunks - 1)  # the whole stream, not its first byte
