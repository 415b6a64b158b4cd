"""The `Host` header checked against the names this server answers to (DNS rebinding).

A web page on `evil.example` whose DNS name is re-pointed at 127.0.0.1 makes the visitor's
browser send it requests to a local `coexist serve`, with `Host: evil.example`; the browser's
same-origin rule holds (the page's origin is still `evil.example`), so that page could read
whatever reads are open. Refusing a `Host` the server is not known by closes it: the rebinding
page never names 127.0.0.1 or `localhost`.

| `COEXIST_ALLOWED_HOSTS`    | the server answers                                                |
|----------------------------|-------------------------------------------------------------------|
| unset, loopback `host`     | `localhost`, `127.0.0.1`, `::1` (any port): local use as before   |
| unset, any other `host`    | any `Host` (a container or a server behind a proxy: set the list) |
| `a.example,*.b.example`    | those names (a leading `*.` for every subdomain), any port        |
| `*`                        | any `Host`                                                        |

A list replaces the loopback names: keep `127.0.0.1` in it where a health check asks
`http://127.0.0.1/...` (the image's HEALTHCHECK does).
Any other `Host` (or none, on HTTP/1.1) is answered 400 `invalid_host` before the request
reaches a route. The check wraps the app that `coexist serve` runs (`served_app`); an app made by
`create_app` alone (in-process tests, embedding) has none. gRPC is not a browser's: unchecked.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from services.app import create_app
from services.registry.errors import error_response
from services.settings import Settings, get_settings

LOOPBACK_HOSTS = ("localhost", "127.0.0.1", "::1")
_LOOPBACK_BINDS = {"127.0.0.1", "localhost", "::1", "[::1]"}


def allowed_hosts(settings: Settings) -> list[str]:
    """The names of the module docstring's table; `["*"]` is any."""
    given = [h.strip().lower() for h in settings.allowed_hosts.split(",") if h.strip()]
    if given:
        return given
    return list(LOOPBACK_HOSTS) if settings.host.strip().lower() in _LOOPBACK_BINDS else ["*"]


def host_name(header: str) -> str:
    """`Host` without its port: `a.example:8000` -> `a.example`, `[::1]:8000` -> `::1`."""
    header = header.strip().lower()
    if header.startswith("["):
        return header[1:].split("]", 1)[0]
    return header.rsplit(":", 1)[0] if header.count(":") == 1 else header


def host_allowed(header: str, allowed: Sequence[str]) -> bool:
    if "*" in allowed:
        return True
    name = host_name(header)
    return any(
        name == pattern or (pattern.startswith("*.") and name.endswith(pattern[1:]))
        for pattern in allowed
    )


class AllowedHosts:
    """ASGI middleware: HTTP and WebSocket requests with a `Host` outside `allowed` get 400.
    The `Host` values found allowed are remembered (up to `REMEMBERED` of them): a client
    sends the same one on every request, and a set look-up is cheaper than the patterns."""

    REMEMBERED = 64

    def __init__(self, app: Any, allowed: Sequence[str]) -> None:
        self.app, self.allowed = app, list(allowed)
        self._any = "*" in self.allowed
        self._seen_allowed: set[bytes] = set()

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if not self._any and scope["type"] in ("http", "websocket"):
            host = b""
            for name, value in scope["headers"]:
                if name == b"host":
                    host = value
                    break
            if host not in self._seen_allowed:
                text = host.decode("latin-1")
                if not host_allowed(text, self.allowed):
                    await self._refuse(text, scope, receive, send)
                    return
                if len(self._seen_allowed) < self.REMEMBERED:
                    self._seen_allowed.add(host)
        await self.app(scope, receive, send)

    async def _refuse(self, host: str, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] == "websocket":  # refuse the upgrade
            await send({"type": "websocket.close", "code": 1008})
            return
        answer = error_response(
            400,
            "invalid_host",
            f"Host {host[:100]!r} is not a name this server answers to (COEXIST_ALLOWED_HOSTS)",
            field="host",
            instance=scope.get("path"),
        )
        await answer(scope, receive, send)


def served_app() -> AllowedHosts:
    """What `coexist serve` runs: `create_app()` behind the `Host` check."""
    return AllowedHosts(create_app(), allowed_hosts(get_settings()))
