"""How many `Episode` streams one client may hold open at once.

On the sync gRPC server each open `Episode` stream holds one of the `max_workers` threads until
the client closes it, so one client opening streams and leaving them open could take every
thread, and with them the server. `EpisodeSlots` bounds the streams of each client (its address,
from the call's peer) to `per_client` (`COEXIST_MAX_EPISODES_PER_CLIENT`, by default half the
workers: `build_grpc_server`); a stream past it waits up to `wait_s` for one of the client's
streams to end (a client that cancels a stream and opens the next at once must not be refused
because the server has not yet seen the cancel), then is `SessionLimitReached`, which the stream
answers with RESOURCE_EXHAUSTED (`services.grpc_api.errors`). Behind a proxy every client has the proxy's
address, so the bound is the proxy's (docker/compose.yaml raises it to the worker count). The
REST sessions' own per-client bound is the session store's.
"""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager

from services.sessions.errors import SessionLimitReached


def client_of(peer: str) -> str:
    """The address of a gRPC peer: `ipv4:10.0.0.7:5123` -> `10.0.0.7`, `ipv6:[::1]:5123` ->
    `::1`; anything else (a Unix socket) is its own client."""
    kind, _, rest = peer.partition(":")
    if kind == "ipv4":
        return rest.rsplit(":", 1)[0]
    if kind == "ipv6":
        return rest.rsplit(":", 1)[0].strip("[]")
    return peer


class EpisodeSlots:
    def __init__(self, per_client: int, wait_s: float = 1.0) -> None:
        if per_client < 1:
            raise ValueError(f"per_client: expected >= 1, got {per_client}")
        self.per_client, self.wait_s = per_client, wait_s
        self._open: Counter[str] = Counter()
        self._freed = threading.Condition()

    @contextmanager
    def held(self, peer: str) -> Iterator[None]:
        """One of the client's slots while the stream runs, or `SessionLimitReached`."""
        client = client_of(peer)
        with self._freed:
            if not self._freed.wait_for(lambda: self._open[client] < self.per_client, self.wait_s):
                raise SessionLimitReached(self.per_client, per_client=True)
            self._open[client] += 1
        try:
            yield
        finally:
            with self._freed:
                self._open[client] -= 1
                if not self._open[client]:
                    del self._open[client]
                self._freed.notify_all()
