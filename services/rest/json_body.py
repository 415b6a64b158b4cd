"""Request bodies parsed with orjson: `FastJsonRoute`, the route class of the inference and
session routers.

FastAPI parses a JSON body with the standard library's `json.loads` (`Request.json()`), which
took 0.9 ms for a 256-row `/v1/act:batch` body on this machine against 0.11 ms for
`orjson.loads` (benchmarks/serving.py: a third of the batch's server time went there). The
route class only swaps the parser; validation, OpenAPI docs and errors stay FastAPI's.

orjson refuses the `NaN` / `Infinity` literals that `json.loads` accepts, and reads integers
beyond 64 bits as floats; for those bodies (an integer literal of 19 or more digits) and
malformed ones the standard parser runs as before, so a NaN observation
or a version number of 10^30 is still refused by the engine's checks naming the field, and
malformed JSON is still the same 422.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Coroutine
from json import loads as standard_loads
from typing import Any

import orjson
from fastapi import Request, Response
from fastapi.routing import APIRoute

# an integer of 19+ digits (orjson would read it as a float); digits after a decimal point, as
# in 0.0066902718999214406, are a float either way
LONG_DIGITS = re.compile(rb"(?<![.0-9])[0-9]{19,}(?![.0-9eE])")


class FastJsonRequest(Request):
    async def json(self) -> Any:
        if not hasattr(self, "_json"):
            body = await self.body()
            try:
                if LONG_DIGITS.search(body):
                    raise orjson.JSONDecodeError("a long integer", "", 0)
                self._json = orjson.loads(body)
            except orjson.JSONDecodeError:  # NaN / Infinity, huge integers, malformed: as before
                self._json = standard_loads(body)
        return self._json


class FastJsonRoute(APIRoute):
    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def route_handler(request: Request) -> Response:
            return await handler(FastJsonRequest(request.scope, request.receive))

        return route_handler
