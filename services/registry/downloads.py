"""Weights downloads that cost the server one copy of a version however many clients download
it, and no more while they read slowly, or not at all.

A download answered with the whole body at once puts all of it in the connection's write
buffer: a client that requests a 55 MB version and reads nothing holds 55 MB of the server's
memory (plus the copy it was made from) for as long as it stays connected. Here

- `SharedWeights.open` loads a version's bytes once (in a worker thread, checksum verified by the
  store) for every download of it in progress; the copy is dropped when the last one ends;
- `WeightsResponse` sends them in `CHUNK_BYTES` pieces, each after the previous one left the
  connection's buffer (the ASGI server's `send` waits while the buffer is full), so a stalled
  client holds at most about one chunk of its own. `services.http_protocol` closes a connection
  whose client read nothing for `COEXIST_HTTP_IDLE_TIMEOUT_S`.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from starlette.concurrency import run_in_threadpool
from starlette.responses import Response
from starlette.types import Receive, Scope, Send

from model_store.artifacts import sha256_hex
from model_store.store import ModelStore

CHUNK_BYTES = 256 << 10


@dataclass(frozen=True)
class Weights:
    """A version's bytes, their sha256, and `release` to call once they were sent."""

    data: bytes
    sha256: str
    release: Callable[[], None]


@dataclass
class _Entry:
    loading: asyncio.Future[tuple[bytes, str]]
    users: int = 0
    key: tuple[int, str, int] = field(default=(0, "", 0))


class SharedWeights:
    """The bytes of the versions being downloaded, one copy per version (module docstring)."""

    def __init__(self) -> None:
        self._entries: dict[tuple[int, str, int], _Entry] = {}

    def __len__(self) -> int:
        return len(self._entries)

    async def open(self, store: ModelStore, name: str, version: int) -> Weights:
        """The version's bytes, loaded unless another download holds them; store errors (not
        found, a checksum mismatch) are raised as `load_weights` raises them."""
        key = (id(store), name, version)
        entry = self._entries.get(key)
        if entry is None:
            loading = asyncio.ensure_future(run_in_threadpool(_load, store, name, version))
            entry = self._entries[key] = _Entry(loading, key=key)
        entry.users += 1
        try:
            data, sha256 = await asyncio.shield(entry.loading)
        except BaseException:
            self._release(entry)
            raise
        return Weights(data, sha256, lambda: self._release(entry))

    def _release(self, entry: _Entry) -> None:
        entry.users -= 1
        if entry.users == 0 and self._entries.get(entry.key) is entry:
            del self._entries[entry.key]


def _load(store: ModelStore, name: str, version: int) -> tuple[bytes, str]:
    data = store.load_weights(name, version)
    return data, sha256_hex(data)


class WeightsResponse(Response):
    """`application/octet-stream` of `weights.data` in `CHUNK_BYTES` pieces, with a
    Content-Length; releases the weights when done, sent or not."""

    media_type = "application/octet-stream"

    def __init__(self, weights: Weights, headers: dict[str, str]) -> None:
        super().__init__(content=None, headers=headers)
        self.weights = weights
        self.headers["content-length"] = str(len(weights.data))

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        data = self.weights.data
        try:
            start: dict[str, Any] = {"type": "http.response.start", "status": self.status_code}
            await send({**start, "headers": self.raw_headers})
            view = memoryview(data)
            for offset in range(0, max(len(data), 1), CHUNK_BYTES):
                chunk = bytes(view[offset : offset + CHUNK_BYTES])
                more = offset + CHUNK_BYTES < len(data)
                await send({"type": "http.response.body", "body": chunk, "more_body": more})
        finally:
            self.weights.release()


DOWNLOADS = SharedWeights()  # the process's downloads in progress
