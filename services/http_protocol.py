"""The HTTP/1.1 connections of `coexist serve`: uvicorn's httptools protocol with the limits it
lacks, so that slow or silent clients cannot hold the server's memory or file descriptors.

uvicorn's httptools protocol bounds neither the request head (httptools joins a header's pieces
as they arrive: a 150 MB header is read, and costs time quadratic in its size) nor the time a
client may take to send it (a connection is timed only between requests, once one was answered),
and accepts connections until the process runs out of file descriptors, after which the store
cannot open its file either. `GuardedHttpProtocol` adds, per connection:

| limit                                  | setting                          | beyond it                |
|----------------------------------------|----------------------------------|--------------------------|
| bytes of a request head (request line  | `COEXIST_HTTP_MAX_HEADER_BYTES`  | 431, connection closed   |
| and headers), counted before httptools | (64 KiB)                         |                          |
| buffers more of it                     |                                  |                          |
| time to send a request head, from the  | `COEXIST_HTTP_HEADER_TIMEOUT_S`  | 408 (or nothing when the |
| connection (or the previous answer)    | (10 s)                           | client sent nothing),    |
|                                        |                                  | connection closed        |
| silence while a request body is due,   | `COEXIST_HTTP_IDLE_TIMEOUT_S`    | connection closed (the   |
| or while an answer waits for the       | (30 s)                           | request sees the client  |
| client to read it                      |                                  | gone)                    |
| idle keep-alive between requests       | `COEXIST_HTTP_KEEP_ALIVE_S` (5 s)| closed (uvicorn's own)   |
| open connections of the process        | `COEXIST_MAX_CONNECTIONS` (the   | the connection without a |
|                                        | file-descriptor limit less       | request in flight that   |
|                                        | `FD_RESERVE`)                    | waited longest is closed |
|                                        |                                  | for the new one; with    |
|                                        |                                  | none such, 503           |

Closing the longest-waiting idle connection, rather than refusing the new one, keeps a server
whose every slot is held by silent sockets answering: a real client sends its request at once and
so is never the one that waited longest. Refusals are answered with the problem details of the
API; after a 431 the server drops what the client still sends for `LINGER_S` before it closes,
so a client that is still sending reads the answer rather than a reset.

On shutdown uvicorn closes every connection without a request in flight at once; one whose
client already sent its next request, still unread in the kernel's buffer, is reset with it.
`GuardedHttpProtocol.shutdown` keeps such a connection until that request is answered (with
`Connection: close`); `services.http_server` keeps the server accepting until it is quiet.

The limits are read from the settings (`services.settings`) when the first connection is made in
a process: uvicorn builds the protocol itself, in each worker.
"""

from __future__ import annotations

import fcntl
import logging
import resource
import struct
import termios
from asyncio import Transport
from dataclasses import dataclass
from typing import Any, ClassVar

from uvicorn.protocols.http.httptools_impl import STATUS_LINE, HttpToolsProtocol

from services.problems import MEDIA_TYPE, problem_bytes
from services.settings import Settings, get_settings

log = logging.getLogger("coexist.server")

FD_RESERVE = 256  # descriptors kept for the store, gRPC, logs and the loaded models' files
MIN_CONNECTIONS = 16
LINGER_S = 1.0  # after a refusal: time for the client to read it while its data is dropped


def connection_cap(configured: int | None) -> int:
    """`configured`, at most what the process's file-descriptor limit leaves beside
    `FD_RESERVE` (None: that much)."""
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY:
        budget = configured or 65536
    else:
        budget = max(MIN_CONNECTIONS, soft - FD_RESERVE)
    return min(configured, budget) if configured else budget


@dataclass(frozen=True)
class HttpLimits:
    max_header_bytes: int
    header_timeout_s: float
    idle_timeout_s: float
    max_connections: int

    @classmethod
    def of(cls, settings: Settings) -> HttpLimits:
        return cls(
            max_header_bytes=settings.http_max_header_bytes,
            header_timeout_s=settings.http_header_timeout_s,
            idle_timeout_s=settings.http_idle_timeout_s,
            max_connections=connection_cap(settings.max_connections),
        )


class GuardedHttpProtocol(HttpToolsProtocol):
    """uvicorn's httptools protocol with the limits of the module docstring."""

    limits: ClassVar[HttpLimits | None] = None  # the process's, read on first use

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if GuardedHttpProtocol.limits is None:
            GuardedHttpProtocol.limits = HttpLimits.of(get_settings())
        self._limits: HttpLimits = GuardedHttpProtocol.limits
        self._in_head = False  # between a request's first byte and the end of its headers
        self._head_bytes = 0
        self._waiting_since = 0.0  # since when the connection waits for a request head
        self._last_data = 0.0
        self._write_paused_since = 0.0
        self._refused = False  # answered with an error: the rest of what it sends is dropped
        self._draining = False  # the server is shutting down: answer what came, then close

    # --- the connection ------------------------------------------------------------------
    def connection_made(self, transport: Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        now = self.loop.time()
        self._waiting_since = self._last_data = now
        if len(self.connections) > self._limits.max_connections and not self._evict_one():
            self._refuse(
                503,
                "too_many_connections",
                f"the server holds its maximum of {self._limits.max_connections} connections, "
                "each with a request in flight (COEXIST_MAX_CONNECTIONS); retry shortly",
            )
            self.transport.close()  # at once: a refusal must not hold a descriptor
            return
        self.loop.call_at(now + self._limits.header_timeout_s, self._check)

    def _evict_one(self) -> bool:
        """Close the connection without a request in flight that waited longest; False when
        every other connection has one."""
        idle = [
            c
            for c in self.connections
            if isinstance(c, GuardedHttpProtocol) and c is not self and c._awaiting_head()
        ]
        if not idle:
            return False
        victim = min(idle, key=lambda c: c._waiting_since)
        self.connections.discard(victim)  # counted out now: its descriptor closes at once
        victim.transport.abort()
        return True

    def data_received(self, data: bytes) -> None:
        if self._refused:
            return
        self._last_data = self.loop.time()
        was_in_head = self._in_head
        super().data_received(data)
        if was_in_head and self._in_head:  # all of `data` belonged to the head
            self._head_bytes += len(data)
            if self._head_bytes > self._limits.max_header_bytes:
                self._refuse(
                    431,
                    "headers_too_large",
                    f"headers: the request line and headers passed "
                    f"{self._limits.max_header_bytes} bytes (COEXIST_HTTP_MAX_HEADER_BYTES)",
                    field="headers",
                )
                # the client may still be sending: it reads the answer, not a reset
                self.loop.call_later(LINGER_S, self.transport.abort)

    def on_message_begin(self) -> None:
        super().on_message_begin()
        self._in_head, self._head_bytes = True, 0

    def on_headers_complete(self) -> None:
        self._in_head = False
        super().on_headers_complete()
        if self._draining and self.cycle is not None:
            self.cycle.keep_alive = False  # the last request of this connection

    def shutdown(self) -> None:
        """The server shuts down: close now unless the client already sent (part of) a
        request, which is read and answered first (module docstring)."""
        self._draining = True
        if self._awaiting_head() and (self._in_head or _unread_bytes(self.transport) > 0):
            return  # the header timeout still bounds a request that never completes
        super().shutdown()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._waiting_since = self.loop.time()

    def pause_writing(self) -> None:
        super().pause_writing()
        self._write_paused_since = self.loop.time()

    # --- timers --------------------------------------------------------------------------
    def _awaiting_head(self) -> bool:
        """No request in flight: the connection waits for the client's next request head."""
        return (self.cycle is None or self.cycle.response_complete) and not self.pipeline

    def _check(self) -> None:
        """Close the connection if its client is late (module docstring), else look again when
        it next could be."""
        transport = self.transport
        if transport.is_closing() or transport.get_protocol() is not self or self._refused:
            return
        now, limits = self.loop.time(), self._limits
        if self._awaiting_head():
            deadline = self._waiting_since + limits.header_timeout_s
            if now >= deadline:
                if self._in_head:  # a client that sent nothing is told nothing
                    message = f"the request head took over {limits.header_timeout_s:g} s"
                    self._refuse(
                        408, "request_timeout", f"{message} (COEXIST_HTTP_HEADER_TIMEOUT_S)"
                    )
                transport.close()
                return
        elif self.flow.write_paused:
            deadline = self._write_paused_since + limits.idle_timeout_s
            if now >= deadline:
                log.info("closing a connection whose client read nothing for %g s", now - deadline)
                transport.abort()  # what it did not read cannot be sent: drop it
                return
        elif self.cycle.more_body and not self.flow.read_paused:
            deadline = self._last_data + limits.idle_timeout_s
            if now >= deadline:
                transport.close()  # the request's receive() sees the client gone
                return
        else:  # the server is working on the request
            deadline = now + limits.header_timeout_s
        self.loop.call_at(deadline, self._check)

    def _refuse(self, status: int, code: str, message: str, field: str | None = None) -> None:
        """Answer `status` with problem details (the API's error shape, `services.problems`) and
        half-close; whatever the client still sends is dropped. The caller closes the
        connection."""
        self._refused = True
        self._unset_keepalive_if_required()
        if self._awaiting_head():  # never into the middle of another answer
            body = problem_bytes(status, code, message, field)
            head = (
                f"content-type: {MEDIA_TYPE}\r\ncontent-length: {len(body)}\r\n"
                "connection: close\r\n\r\n"
            )
            self.transport.write(STATUS_LINE[status] + head.encode() + body)
            if self.transport.can_write_eof():
                self.transport.write_eof()


def _unread_bytes(transport: Transport) -> int:
    """Bytes the kernel received on the connection that the server has not read yet."""
    sock = transport.get_extra_info("socket")
    if sock is None:
        return 0
    try:
        unread: int = struct.unpack("i", fcntl.ioctl(sock.fileno(), termios.FIONREAD, b"\0" * 4))[0]
    except (OSError, ValueError):  # closed meanwhile
        return 0
    return unread
