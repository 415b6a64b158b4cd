"""`SessionStore`: the REST sessions of one server process, in memory, bounded and expiring.

    store = SessionStore(engine, max_sessions=1000, max_per_client=100, ttl_s=300.0)
    info = store.create(SessionSettings("particle", "a2", (SessionPartner(1, infer=True),)),
                        client="10.0.0.7")
    answer = store.step(info.session_id, obs, observed=[Observed(1, 3)], expected_step=1)
    store.get(info.session_id); store.delete(info.session_id)

| rule        | what                                                                          |
|-------------|-------------------------------------------------------------------------------|
| ids         | `secrets.token_urlsafe(16)`: 128 random bits, unguessable                     |
| expiry      | a session idle for `ttl_s` (no step since) is gone: the next request gets     |
|             | `SessionNotFound` saying so. `get` reads without extending the idle time      |
| bound       | `create` purges expired sessions first, then refuses beyond `max_sessions`,   |
|             | or beyond `max_per_client` for the creating client (`SessionLimitReached`,    |
|             | with the seconds until the first slot that could free up: the oldest idle     |
|             | session's expiry, which REST sends as `Retry-After`)                          |
| concurrency | a store lock guards the table only; each session's own lock serialises its    |
|             | steps, so steps of different sessions run in parallel                         |
| lost ids    | the last `max_sessions` expired or deleted ids are remembered, so a late      |
|             | request learns which of the two happened                                      |

Sessions live in this process's memory: another process (a second `--workers` worker, another
replica) does not know them; see docs/architecture.md "Sessions" for routing.
"""

from __future__ import annotations

import secrets
import threading
import time
from collections import Counter, OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from services.engine import InferenceEngine
from services.sessions.errors import SessionLimitReached, SessionNotFound
from services.sessions.messages import Observed, SessionInfo, SessionSettings, SessionStepResult
from services.sessions.session import Session


@dataclass
class _Entry:
    session: Session
    last_used: float  # clock() at the end of the last step (or at creation)
    client: str  # who created it (REST: the client's address)


class SessionStore:
    """In-memory sessions of one process (module docstring)."""

    def __init__(
        self,
        engine: InferenceEngine,
        *,
        max_sessions: int = 1000,
        max_per_client: int | None = None,
        ttl_s: float = 300.0,
        clock: Callable[[], float] = time.monotonic,
        prefetch: bool = True,
    ) -> None:
        if max_sessions < 1:
            raise ValueError(f"max_sessions: expected >= 1, got {max_sessions}")
        if not ttl_s > 0:
            raise ValueError(f"ttl_s: expected > 0, got {ttl_s}")
        if max_per_client is not None and max_per_client < 1:
            raise ValueError(f"max_per_client: expected >= 1, got {max_per_client}")
        self.engine = engine
        self.max_sessions = max_sessions
        self.max_per_client = max_per_client or max_sessions
        self.ttl_s = ttl_s
        self.prefetch = prefetch  # sessions score the next step's evidence ahead
        self._clock = clock
        self._lock = threading.Lock()
        self._sessions: dict[str, _Entry] = {}
        self._per_client: Counter[str] = Counter()
        self._gone: OrderedDict[str, str] = OrderedDict()  # id -> why it is gone

    def __len__(self) -> int:
        with self._lock:
            return len(self._sessions)

    # --- operations ------------------------------------------------------------------------
    def create(self, settings: SessionSettings, client: str = "") -> SessionInfo:
        """A new session of `client` (settings checked first: `InvalidRequest` naming the
        field); `SessionLimitReached` beyond either bound (module docstring)."""
        session = Session(self.engine, settings, secrets.token_urlsafe(16), prefetch=self.prefetch)
        with self._lock:
            now = self._clock()
            full = len(self._sessions) >= self.max_sessions
            if full or self._per_client[client] >= self.max_per_client:
                self._purge_expired(now)
            if len(self._sessions) >= self.max_sessions:
                raise SessionLimitReached(self.max_sessions, self._first_free(now, None))
            if self._per_client[client] >= self.max_per_client:
                retry = self._first_free(now, client)
                raise SessionLimitReached(self.max_per_client, retry, per_client=True)
            self._sessions[session.session_id] = _Entry(session, now, client)
            self._per_client[client] += 1
        return self._info(session, self.ttl_s)

    def step(
        self,
        session_id: str,
        observation: object,
        observed: Sequence[Observed] = (),
        expected_step: int | None = None,
    ) -> SessionStepResult:
        """One step of the session (`Session.step`); its idle time restarts afterwards."""
        entry = self._entry(session_id)
        result = entry.session.step(observation, observed, expected_step)
        with self._lock:
            entry.last_used = self._clock()
        return result

    def prepare_next(self, session_id: str) -> bool:
        """`Session.prepare_next` of the session, if it is still here (a transport calls it
        after sending a step's answer; a session gone meanwhile is no error)."""
        with self._lock:
            entry = self._sessions.get(session_id)
        return entry is not None and entry.session.prepare_next()

    def settings(self, session_id: str) -> SessionSettings:
        """The session's settings (cheap: no belief summary), or `SessionNotFound`."""
        return self._entry(session_id).session.settings

    def get(self, session_id: str) -> SessionInfo:
        entry = self._entry(session_id)
        return self._info(entry.session, self._expires_in(entry, self._clock()))

    def delete(self, session_id: str) -> None:
        with self._lock:
            self._entry_locked(session_id, self._clock())
            self._remove(session_id, "it was deleted")

    def purge_expired(self) -> int:
        """Drop every expired session now; how many there were."""
        with self._lock:
            return self._purge_expired(self._clock())

    # --- helpers (the `_locked` and `_purge` ones expect the store lock held) -------------------
    def _entry(self, session_id: str) -> _Entry:
        with self._lock:
            return self._entry_locked(session_id, self._clock())

    def _entry_locked(self, session_id: str, now: float) -> _Entry:
        entry = self._sessions.get(session_id) if isinstance(session_id, str) else None
        if entry is not None and self._expires_in(entry, now) <= 0:
            self._remove(session_id, self._expired_why())
            entry = None
        if entry is None:
            why = self._gone.get(session_id) if isinstance(session_id, str) else None
            raise SessionNotFound(
                str(session_id),
                why
                or f"{self._expired_why()}, was deleted, or was created by another server "
                "process (sessions live in the memory of the process that created them)",
            )
        return entry

    def _expired_why(self) -> str:
        return f"it expired after {self.ttl_s:g} s idle"

    def _expires_in(self, entry: _Entry, now: float) -> float:
        return self.ttl_s - (now - entry.last_used)

    def _purge_expired(self, now: float) -> int:
        expired = [sid for sid, e in self._sessions.items() if self._expires_in(e, now) <= 0]
        for sid in expired:
            self._remove(sid, self._expired_why())
        return len(expired)

    def _first_free(self, now: float, client: str | None) -> float:
        """Seconds until the first of `client`'s sessions (None: of all) could expire."""
        left = [
            self._expires_in(e, now)
            for e in self._sessions.values()
            if client is None or e.client == client
        ]
        return max(0.0, min(left, default=0.0))

    def _remove(self, session_id: str, why: str) -> None:
        entry = self._sessions.pop(session_id)
        self._per_client[entry.client] -= 1
        if not self._per_client[entry.client]:
            del self._per_client[entry.client]
        self._forget(session_id, why)

    def _forget(self, session_id: str, why: str) -> None:
        self._gone[session_id] = why
        while len(self._gone) > self.max_sessions:
            self._gone.popitem(last=False)

    @staticmethod
    def _info(session: Session, expires_in_s: float) -> SessionInfo:
        step, beliefs = session.snapshot()
        return SessionInfo(
            session_id=session.session_id,
            settings=session.settings,
            step=step,
            beliefs=beliefs,
            expires_in_s=max(0.0, expires_in_s),
        )
