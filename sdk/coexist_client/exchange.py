"""How one set of client methods serves both sync and async callers.

Every SDK method is written once, as a *plan*: a generator that yields the exchanges it needs
(an HTTP request, a gRPC call, a step on an open stream), receives each one's answer, and
returns the method's result. It does no I/O itself. A transport (`coexist_client.transport`)
performs exchanges, blocking or awaited; `drive` and `adrive` run a plan on one, retrying
exchanges that failed on the way to the server. `blocking(plan)` and `awaiting(plan)` turn a
plan function into a sync or async method with the same parameters, so `Client.act` and
`AsyncClient.act` share one signature, one body builder and one answer parser.

    def act(core, env, ego_goal, observation=None, ...) -> Plan[Action]:
        data = yield core.transport.act_exchange(act_body(...))
        return ...
    class Client(Core):      act = blocking(act)         # client.act(...) -> Action
    class AsyncClient(Core): act = awaiting(act)         # await client.act(...) -> Action

Retries: an exchange whose failure is `Unavailable` (no connection, HTTP 503, gRPC
UNAVAILABLE) is tried again up to `Retry.attempts - 1` times, waiting `backoff_s`, then twice
that, and so on (capped at `max_backoff_s`). A request the server may have seen (a read
timeout, a dropped connection after sending) is retried only where the exchange is idempotent.
"""

from __future__ import annotations

import asyncio
import inspect
import time
from collections.abc import Awaitable, Callable, Generator
from dataclasses import dataclass
from typing import Any, Concatenate, ParamSpec, Protocol, Self, TypeVar

from coexist_client.errors import CoexistError, Unavailable

T = TypeVar("T")
P = ParamSpec("P")

# A plan yields exchanges, is sent each one's answer and returns the method's result.
Plan = Generator[Any, Any, T]


@dataclass(frozen=True)
class Retry:
    """How often and how patiently an exchange is retried (see the module docstring)."""

    attempts: int = 3  # tries in all, the first included; 1: never retry
    backoff_s: float = 0.1
    max_backoff_s: float = 2.0

    def wait_s(self, failures: int) -> float:
        return float(min(self.backoff_s * 2 ** (failures - 1), self.max_backoff_s))


class Transport(Protocol):
    """What performs exchanges: `HttpTransport` or `GrpcTransport`."""

    retry: Retry

    def send(self, exchange: Any) -> Any: ...
    async def asend(self, exchange: Any) -> Any: ...


def _retryable(err: CoexistError, exchange: Any, failures: int, retry: Retry) -> bool:
    if failures >= retry.attempts or not isinstance(err, Unavailable):
        return False
    if not getattr(exchange, "retry", True):
        return False
    # not sent (or refused unseen by a 503): safe; otherwise only an idempotent exchange
    return bool(getattr(err, "unsent", False) or getattr(exchange, "idempotent", True))


def drive(transport: Transport, plan: Plan[T]) -> T:
    """Run `plan` to its result, performing its exchanges on `transport` (blocking)."""
    answer: Any = None
    error: CoexistError | None = None
    while True:
        try:
            exchange = plan.send(answer) if error is None else plan.throw(error)
        except StopIteration as done:
            return done.value
        answer, error, failures = None, None, 0
        while True:
            try:
                answer = transport.send(exchange)
                break
            except CoexistError as err:
                failures += 1
                if not _retryable(err, exchange, failures, transport.retry):
                    error = err
                    break
                time.sleep(transport.retry.wait_s(failures))


async def adrive(transport: Transport, plan: Plan[T]) -> T:
    """`drive`, awaited: the same plan, each exchange awaited."""
    answer: Any = None
    error: CoexistError | None = None
    while True:
        try:
            exchange = plan.send(answer) if error is None else plan.throw(error)
        except StopIteration as done:
            return done.value
        answer, error, failures = None, None, 0
        while True:
            try:
                answer = await transport.asend(exchange)
                break
            except CoexistError as err:
                failures += 1
                if not _retryable(err, exchange, failures, transport.retry):
                    error = err
                    break
                await asyncio.sleep(transport.retry.wait_s(failures))


class Core:
    """What every plan reads: the transport it yields exchanges for."""

    transport: Any


class Closing(Core):
    """A sync client's `close()` and `with` block (the transport's connections released)."""

    def close(self) -> None:
        self.transport.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


class AsyncClosing(Core):
    """An async client's `aclose()` and `async with` block."""

    async def aclose(self) -> None:
        await self.transport.aclose()

    async def __aenter__(self) -> Self:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.aclose()


C = TypeVar("C", bound=Core)


def blocking(plan: Callable[Concatenate[C, P], Plan[T]]) -> Callable[Concatenate[C, P], T]:
    """A sync method running `plan` (same parameters, its result returned)."""

    def method(self: C, /, *args: P.args, **kwargs: P.kwargs) -> T:
        return drive(self.transport, plan(self, *args, **kwargs))

    return _documented(method, plan, sync=True)


def awaiting(
    plan: Callable[Concatenate[C, P], Plan[T]],
) -> Callable[Concatenate[C, P], Awaitable[T]]:
    """An async method running `plan` (same parameters, its result awaited)."""

    async def method(self: C, /, *args: P.args, **kwargs: P.kwargs) -> T:
        return await adrive(self.transport, plan(self, *args, **kwargs))

    return _documented(method, plan, sync=False)


W = TypeVar("W")


def opening(
    plan: Callable[Concatenate[C, P], Plan[T]], wrap: Callable[[Any, T], W]
) -> Callable[Concatenate[C, P], W]:
    """A sync method running `plan` and handing its result, with the transport, to `wrap` (a
    session class: `wrap(transport, opened)`)."""

    def method(self: C, /, *args: P.args, **kwargs: P.kwargs) -> W:
        return wrap(self.transport, drive(self.transport, plan(self, *args, **kwargs)))

    return _documented(method, plan, sync=True)


def awaiting_opening(
    plan: Callable[Concatenate[C, P], Plan[T]], wrap: Callable[[Any, T], W]
) -> Callable[Concatenate[C, P], Awaitable[W]]:
    """`opening`, awaited."""

    async def method(self: C, /, *args: P.args, **kwargs: P.kwargs) -> W:
        return wrap(self.transport, await adrive(self.transport, plan(self, *args, **kwargs)))

    return _documented(method, plan, sync=False)


F = TypeVar("F", bound=Callable[..., Any])


def _documented(method: F, plan: Callable[..., Any], *, sync: bool) -> F:
    """`method` named, documented and signed as `plan` (help() and IDEs show its parameters),
    its return annotation the plan's result (awaited for async methods)."""
    method.__name__ = method.__qualname__ = plan.__name__
    method.__doc__ = plan.__doc__
    signature = inspect.signature(plan)
    result = str(signature.return_annotation).removeprefix("Plan[").removesuffix("]")
    method.__signature__ = signature.replace(  # type: ignore[attr-defined]
        return_annotation=result if sync else f"Awaitable[{result}]"
    )
    return method
