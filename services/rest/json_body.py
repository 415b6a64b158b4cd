"""Request bodies parsed with orjson: `FastJsonRoute`, the route class of the inference and
session routers.

FastAPI parses a JSON body with the standard library's `json.loads` (`Request.json()`), several
times slower than `orjson.loads` on a batch body of numbers (docs/performance.md). The route class only swaps the parser; validation, OpenAPI docs and errors stay
FastAPI's.

A body of `OFFLOAD_BYTES` or more is parsed in a worker thread, so the event loop goes on
serving other requests meanwhile (together with the size limit of `services.rest.body_limit` and
the fail-fast body models of `services.rest.bounded`, which keep the work of refusing a bad body
small, this is what keeps a large body from stalling `/healthz`).

Where orjson reads a body differently, the standard parser runs as before:
- orjson refuses the `NaN` / `Infinity` literals that `json.loads` accepts (and malformed JSON):
  a NaN observation is still refused by the engine's checks naming the field, malformed JSON
  is still the same 422; a string with a lone surrogate (`"\\ud800"`), which `json.loads`
  accepts and nothing downstream can encode as UTF-8, is a 422 too (as orjson says), and so is
  a body nested deeper than the standard parser's recursion goes;
- orjson reads an integer beyond 64 bits as a float. Every integer field of these bodies (seed,
  indices, versions, expected_step) is a scalar in an object, so a float of magnitude >= 2^63
  there sends the body to the standard parser (a version number of 10^30 is still the engine's
  422 naming `versions[...]`). Vectors and matrices of numbers (observations, states) are not
  walked: they are floats either way, and walking every row of a batch would cost time.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Coroutine
from json import JSONDecodeError
from json import loads as standard_loads
from typing import Any

import orjson
from fastapi import Request, Response
from fastapi.routing import APIRoute
from starlette.concurrency import run_in_threadpool

HUGE = 2.0**63  # orjson turns integer literals from here on into floats
OFFLOAD_BYTES = 1 << 20  # bodies from this size on are parsed in a worker thread
_SURROGATE = re.compile("[\ud800-\udfff]")


def has_huge_scalar(value: Any) -> bool:
    """Whether a parsed body holds a float >= 2^63 in magnitude outside a vector of numbers (a
    walk with a stack of its own: one call per body, not per value)."""
    pending = [value]
    while pending:
        item = pending.pop()
        kind = type(item)
        if kind is float:
            if abs(item) >= HUGE:
                return True
        elif kind is dict:
            pending.extend(item.values())
        elif kind is list and item:
            first = item[0]
            if isinstance(first, int | float):
                continue  # a vector of numbers: floats either way
            if type(first) is list and first and isinstance(first[0], int | float):
                continue  # rows of numbers (observations): no integer field is a matrix
            pending.extend(item)
    return False


def has_lone_surrogate(value: Any) -> bool:
    """Whether a parsed body holds a string (key or value) with a lone UTF-16 surrogate, which
    `json.loads` accepts from a `\\ud800` escape and no UTF-8 encoder (database, logs, answer)
    can write."""
    pending = [value]
    while pending:
        item = pending.pop()
        if type(item) is str:
            if _SURROGATE.search(item):
                return True
        elif type(item) is dict:
            pending.extend(item.keys())
            pending.extend(item.values())
        elif type(item) is list:
            pending.extend(item)
    return False


def parse_json(body: bytes) -> Any:
    """orjson, or the standard parser where it reads a body differently (module docstring)."""
    try:
        parsed = orjson.loads(body)
    except orjson.JSONDecodeError as err:  # NaN / Infinity literals, malformed: as before
        try:
            parsed = standard_loads(body)
            readable = not has_lone_surrogate(parsed)  # else not valid Unicode, as orjson says
        except RecursionError:  # nested deeper than the standard parser goes (orjson: 1024)
            readable = False
        if not readable:  # the body's 422, as for malformed JSON
            raise JSONDecodeError(str(err), body.decode(errors="replace"), 0) from None
        return parsed
    if has_huge_scalar(parsed):  # an integer orjson read as a float: as before
        return standard_loads(body)
    return parsed


class FastJsonRequest(Request):
    async def json(self) -> Any:
        if not hasattr(self, "_json"):
            body = await self.body()
            if len(body) < OFFLOAD_BYTES:
                self._json = parse_json(body)
            else:  # off the event loop: other requests go on meanwhile
                self._json = await run_in_threadpool(parse_json, body)
        return self._json


class FastJsonRoute(APIRoute):
    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def route_handler(request: Request) -> Response:
            return await handler(FastJsonRequest(request.scope, request.receive))

        return route_handler
