"""The HTTP server of `coexist serve`: uvicorn's, with a shutdown that answers every request its
clients had already sent.

uvicorn's shutdown closes the listening socket first, then every connection without a request in
flight. Under load the event loop runs the engine between reads (the inference handlers call it
directly), so requests that clients sent in full can still wait unread: in the listening
socket's queue (not yet accepted) or in a connection's kernel buffer. Closing resets both, and
the clients see their requests fail a moment after SIGTERM, well inside the grace period.

`DrainingServer.shutdown` first keeps serving, accepting included, until no request has been in
flight for `QUIET_S` (an idle event loop has by then accepted every queued connection and read
every buffer), or until the grace period (`COEXIST_SHUTDOWN_GRACE_S`) runs out; uvicorn's own
shutdown follows with what is left of the grace period, and `GuardedHttpProtocol.shutdown` answers
any request that arrives in between before closing its connection. A load balancer should stop
sending new requests once the process is signalled (docker/compose.yaml's Envoy does when a
replica leaves).

With `--workers N` (N > 1) uvicorn's supervisor builds the workers' servers itself, so only the
connection-level part applies there (`serve`).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import sys
from typing import Any

import uvicorn

log = logging.getLogger("coexist.server")

QUIET_S = 0.3  # no request in flight for this long: the queues are empty
POLL_S = 0.02
STARTUP_FAILURE = 3  # uvicorn's exit status when the app does not start


class DrainingServer(uvicorn.Server):
    """`uvicorn.Server` whose shutdown first drains what clients already sent."""

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        loop = asyncio.get_running_loop()
        grace = float(self.config.timeout_graceful_shutdown or 0)
        start = loop.time()
        deadline = start + grace
        quiet_since = start
        while not self.force_exit and (now := loop.time()) < deadline:
            if self.server_state.tasks:
                quiet_since = now
            elif now - quiet_since >= QUIET_S:
                break
            await asyncio.sleep(POLL_S)
        left = deadline - loop.time()
        log.info("requests already sent answered in %.1f s; closing connections", grace - left)
        self.config.timeout_graceful_shutdown = max(1, int(left + 0.999))
        await super().shutdown(sockets)


def serve(app: str, **config: Any) -> None:
    """`uvicorn.run(app, factory=True, **config)`, with `DrainingServer` in a single process."""
    if config.get("workers", 1) > 1:
        uvicorn.run(app, factory=True, **config)
        return
    settings = uvicorn.Config(app, factory=True, **config)
    settings.load_app()
    server = DrainingServer(settings)
    with contextlib.suppress(KeyboardInterrupt):  # a second Ctrl-C: uvicorn's force quit
        server.run()
    if not server.started:
        sys.exit(STARTUP_FAILURE)
