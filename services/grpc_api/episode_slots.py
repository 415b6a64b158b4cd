"""How many `Episode` streams may be open at once, and how long one may stay silent.

On the sync gRPC server each open `Episode` stream holds one of the `max_workers` threads until
it ends, so streams left open could take every thread, and with them `Act`, `ActBatch` and the
rest. Three bounds keep threads for the unary calls (health checks have a pool of their own,
`server.build_grpc_server`):

| bound                      | setting                           | default            | beyond it          |
|----------------------------|-----------------------------------|--------------------|--------------------|
| streams of all clients     | `COEXIST_MAX_EPISODES`            | half the workers   | RESOURCE_EXHAUSTED |
|                            |                                   | (always fewer)     |                    |
| streams of one client      | `COEXIST_MAX_EPISODES_PER_CLIENT` | `MAX_EPISODES`     | RESOURCE_EXHAUSTED |
| silence between two steps  | `COEXIST_EPISODE_IDLE_TIMEOUT_S`  | 60 s               | DEADLINE_EXCEEDED  |

`EpisodeSlots` counts the streams of each client (its address, from the call's peer) and of all
of them; a stream past a bound waits up to `wait_s` for a slot (a client that cancels a stream
and opens the next at once must not be refused because the server has not yet seen the cancel),
then is `SessionLimitReached`. Behind a proxy every client has the proxy's address, so the
per-client bound is the proxy's (docker/compose.yaml raises it to the shared one). The REST
sessions' own bounds are the session store's.

`steps_within` ends a stream whose client sent nothing for the idle timeout with `EpisodeIdle`:
grpcio's request iterator blocks without a timeout, so a small reader thread per stream waits on
it and hands the steps over through a queue the worker waits on with one.
"""

from __future__ import annotations

import queue
import threading
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TypeVar

from services.engine.errors import EngineError
from services.sessions.errors import SessionLimitReached

Step = TypeVar("Step")
OPEN_STREAMS = "open Episode streams"
REMEDY = "close finished Episode streams (end the request stream) or retry when one closes"


class EpisodeIdle(EngineError):
    """No step arrived for `idle_s` seconds: the server ended the stream (DEADLINE_EXCEEDED)."""

    code = "episode_idle"

    def __init__(self, idle_s: float) -> None:
        super().__init__(
            None,
            f"no step for {idle_s:g} s: the server ended this idle Episode stream "
            "(COEXIST_EPISODE_IDLE_TIMEOUT_S); open a new stream to go on",
        )
        self.idle_s = idle_s


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
    """At most `total` open streams, and `per_client` of one client (None: `total`)."""

    def __init__(self, total: int, per_client: int | None = None, wait_s: float = 1.0) -> None:
        if total < 1:
            raise ValueError(f"total: expected >= 1, got {total}")
        per_client = total if per_client is None else per_client
        if per_client < 1:
            raise ValueError(f"per_client: expected >= 1, got {per_client}")
        self.total, self.per_client, self.wait_s = total, min(per_client, total), wait_s
        self._open: Counter[str] = Counter()
        self._freed = threading.Condition()

    @property
    def open_streams(self) -> int:
        with self._freed:
            return sum(self._open.values())

    @contextmanager
    def held(self, peer: str) -> Iterator[None]:
        """One of the client's slots while the stream runs, or `SessionLimitReached`."""
        client = client_of(peer)
        with self._freed:
            if not self._freed.wait_for(lambda: self._free_for(client), self.wait_s):
                if sum(self._open.values()) >= self.total:
                    raise SessionLimitReached(self.total, what=OPEN_STREAMS, remedy=REMEDY)
                raise SessionLimitReached(
                    self.per_client, per_client=True, what=OPEN_STREAMS, remedy=REMEDY
                )
            self._open[client] += 1
        try:
            yield
        finally:
            with self._freed:
                self._open[client] -= 1
                if not self._open[client]:
                    del self._open[client]
                self._freed.notify_all()

    def _free_for(self, client: str) -> bool:
        return self._open[client] < self.per_client and sum(self._open.values()) < self.total


_END = object()  # the reader's last item: the client half-closed the stream


def steps_within(requests: Iterator[Step], idle_s: float) -> Iterator[Step]:
    """The steps of `requests`, ending with `EpisodeIdle` when none came for `idle_s` seconds.

    The reader thread stops with the call: once the handler returns, grpcio ends the call and the
    blocked `next` ends (StopIteration, or an error for a cancelled call)."""
    handed: queue.SimpleQueue[object] = queue.SimpleQueue()

    def read() -> None:
        try:
            for step in requests:
                handed.put(step)
            handed.put(_END)
        except BaseException as err:  # the call was cancelled, or a step failed to arrive
            handed.put(err)

    threading.Thread(target=read, name="coexist-episode-reader", daemon=True).start()
    while True:
        try:
            item = handed.get(timeout=idle_s)
        except queue.Empty:
            raise EpisodeIdle(idle_s) from None
        if item is _END:
            return
        if isinstance(item, BaseException):
            raise item
        yield item  # type: ignore[misc]
