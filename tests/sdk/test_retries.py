"""`coexist_client.exchange`: retries with backoff (connection errors, HTTP 503, gRPC
UNAVAILABLE), never for a request the server may have acted on unless it is idempotent; and one
plan serving both the sync and the async client."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

import grpc
import httpx
import pytest
from coexist_client import (
    AsyncClient,
    Client,
    InvalidArgument,
    JobsClient,
    Retry,
    Unavailable,
)

ACTION = {
    "probs": [0.5, 0.5],
    "action": 1,
    "greedy_action": 0,
    "action_meaning": "up",
    "method": "sl",
    "diagnostics": {"task_entropy": 1.0, "task_weight": 1.0},
}
FAST = Retry(attempts=3, backoff_s=0.001)


def _answers(*steps: Callable[[httpx.Request], httpx.Response]) -> tuple[list[str], object]:
    seen: list[str] = []

    def handler(request: httpx.Request) -> httpx.Response:
        seen.append(request.url.path)
        return steps[min(len(seen), len(steps)) - 1](request)

    return seen, httpx.MockTransport(handler)


def ok(_: httpx.Request) -> httpx.Response:
    return httpx.Response(200, json=ACTION)


def busy(_: httpx.Request) -> httpx.Response:
    return httpx.Response(503, json={"error": {"code": "unavailable", "message": "busy"}})


def refused(request: httpx.Request) -> httpx.Response:
    raise httpx.ConnectError("refused", request=request)


def timed_out(request: httpx.Request) -> httpx.Response:
    raise httpx.ReadTimeout("no answer", request=request)


def test_a_503_and_a_refused_connection_are_retried() -> None:
    seen, transport = _answers(busy, refused, ok)
    with Client("http://mock", transport=transport, retry=FAST) as client:
        assert client.act("particle", "a2", [0.0] * 8).action == 1
    assert seen == ["/v1/act"] * 3


def test_retries_stop_after_the_attempts_with_the_last_error() -> None:
    seen, transport = _answers(busy)
    with (
        Client("http://mock", transport=transport, retry=FAST) as client,
        pytest.raises(Unavailable),
    ):
        client.act("particle", "a2", [0.0] * 8)
    assert len(seen) == 3


def test_backoff_doubles_up_to_its_cap() -> None:
    retry = Retry(attempts=5, backoff_s=0.1, max_backoff_s=0.3)
    assert [retry.wait_s(k) for k in (1, 2, 3, 4)] == [0.1, 0.2, 0.3, 0.3]
    _, transport = _answers(busy, busy, ok)
    start = time.monotonic()
    with Client("http://mock", transport=transport, retry=Retry(3, 0.05)) as client:
        client.act("particle", "a2", [0.0] * 8)
    assert time.monotonic() - start >= 0.05 + 0.1


def test_a_bad_request_is_never_retried() -> None:
    def bad(_: httpx.Request) -> httpx.Response:
        body = {"error": {"code": "invalid", "message": "observation: no", "field": "observation"}}
        return httpx.Response(400, json=body)

    seen, transport = _answers(bad)
    with (
        Client("http://mock", transport=transport, retry=FAST) as client,
        pytest.raises(InvalidArgument) as info,
    ):
        client.act("particle", "a2", [0.0] * 8)
    assert info.value.field == "observation" and len(seen) == 1


def test_a_job_submission_the_server_may_have_seen_is_not_sent_twice() -> None:
    seen, transport = _answers(timed_out)
    with (
        JobsClient("http://mock", transport=transport, retry=FAST) as jobs,
        pytest.raises(Unavailable),
    ):
        jobs.submit("task", goals="a2")
    assert seen == ["/v1/jobs"]  # a read timeout: maybe queued already
    seen, transport = _answers(timed_out)
    with (
        Client("http://mock", transport=transport, retry=FAST) as client,
        pytest.raises(Unavailable),
    ):
        client.act("particle", "a2", [0.0] * 8)
    assert len(seen) == 3  # an act is idempotent (seeded): tried again


def test_the_async_client_runs_the_same_plans() -> None:
    seen: list[str] = []

    async def run() -> int:
        def handler(request: httpx.Request) -> httpx.Response:
            seen.append(request.url.path)
            return busy(request) if len(seen) == 1 else ok(request)

        transport = httpx.MockTransport(handler)
        async with AsyncClient("http://mock", transport=transport, retry=FAST) as client:
            return (await client.act("particle", "a2", [0.0] * 8)).action

    assert asyncio.run(run()) == 1
    assert seen == ["/v1/act", "/v1/act"]


def test_grpc_unavailable_is_retried_then_reported() -> None:
    # nothing listens on the port: every try is UNAVAILABLE, each one retried
    client = Client("grpc://127.0.0.1:1", retry=Retry(2, 0.001), timeout=2.0)
    with client, pytest.raises(Unavailable) as info:
        client.act("particle", "a2", [0.0] * 8)
    assert info.value.code == grpc.StatusCode.UNAVAILABLE.name.lower()
