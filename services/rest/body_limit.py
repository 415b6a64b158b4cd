"""`BodyLimit`: request bodies over a size limit are refused with 413 before they are read.

A pure ASGI middleware (no Starlette request objects, nothing per request beyond one pass over
the headers):

| request                                   | what happens                                       |
|-------------------------------------------|----------------------------------------------------|
| `Content-Length` over the limit           | 413 at once, nothing of the body read; the answer  |
|                                           | says `Connection: close` (the rest is never read)  |
| `Content-Length` within the limit         | passed through untouched (the server reads at most |
|                                           | that many bytes)                                   |
| `Transfer-Encoding: chunked`              | the chunks are counted as the app reads them; at   |
|                                           | the first byte over the limit the client gets 413  |
|                                           | and the app a disconnect (its own answer is        |
|                                           | dropped)                                           |

Two limits: `upload_max_bytes` for a version upload (`POST .../-/versions`, multipart: the
weights' limit plus the form's overhead, `services.registry.versions_routes`), `max_bytes` for
every other route (JSON; `COEXIST_MAX_BODY_BYTES`). The 413 is the usual problem details body
(`services.problems`) naming the limit and the setting: code `body_too_large`, field `body` (an
upload: the route's own `artifact_too_large`, field `weights`).
"""

from __future__ import annotations

from typing import Any

from services.problems import MEDIA_TYPE, problem_bytes

UPLOAD_SUFFIX = "/-/versions"
Message = dict[str, Any]


class BodyLimit:
    def __init__(self, app: Any, *, max_bytes: int, upload_max_bytes: int) -> None:
        self.app = app
        self.max_bytes, self.upload_max_bytes = max_bytes, upload_max_bytes

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        upload = scope["method"] == "POST" and scope["path"].endswith(UPLOAD_SUFFIX)
        limit = self.upload_max_bytes if upload else self.max_bytes
        chunked = False
        for name, value in scope["headers"]:
            if name == b"content-length":
                if value.isdigit() and int(value) > limit:
                    await _refuse(scope, send, f"{int(value)} bytes is over", limit, upload)
                    return
                break  # within the limit: the server delivers no more than it declared
            if name == b"transfer-encoding":
                chunked = True
        if chunked:
            await self._counted(scope, receive, send, limit, upload)
        else:
            await self.app(scope, receive, send)

    async def _counted(
        self, scope: dict[str, Any], receive: Any, send: Any, limit: int, upload: bool
    ) -> None:
        """Run the app on a body counted as it streams (module docstring)."""
        received, refused, started = 0, False, False

        async def counted_receive() -> Message:
            nonlocal received, refused
            if refused:
                return {"type": "http.disconnect"}
            message: Message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    refused = True
                    if not started:
                        await _refuse(scope, send, "the streamed body went", limit, upload)
                    return {"type": "http.disconnect"}
            return message

        async def guarded_send(message: Message) -> None:
            nonlocal started
            if refused:
                return  # the app's answer to a body it never got whole: the 413 went instead
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, counted_receive, guarded_send)
        except Exception:
            if not refused:
                raise  # a failure of its own, not the disconnect the app was handed


async def _refuse(scope: dict[str, Any], send: Any, what: str, limit: int, upload: bool) -> None:
    if upload:  # as the upload route itself says it (`ArtifactTooLarge`)
        code, field, setting = "artifact_too_large", "weights", "COEXIST_MAX_ARTIFACT_BYTES + 1 MiB"
    else:
        code, field, setting = "body_too_large", "body", "COEXIST_MAX_BODY_BYTES"
    message = f"body: {what} the limit of {limit} bytes ({setting})"
    body = problem_bytes(413, code, message, field, instance=scope.get("path"))
    headers = [
        (b"content-type", MEDIA_TYPE.encode()),
        (b"content-length", str(len(body)).encode()),
        (b"connection", b"close"),
    ]
    await send({"type": "http.response.start", "status": 413, "headers": headers})
    await send({"type": "http.response.body", "body": body})
