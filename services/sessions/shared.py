"""`SharedSessionStore`: REST sessions kept in Redis or PostgreSQL, so that any worker process
and any replica of a deployment serves any step of any session.

    store = SharedSessionStore(engine, open_backend(url, codec.namespace()), codec, ttl_s=300)
    info = store.create(settings, client="10.0.0.7")   # the same calls as `SessionStore`
    answer = store.step(info.session_id, obs, observed=[Observed(1, 3)], expected_step=1)

A step reads the session's record (only its version, when this process holds the stored
version already: it served the previous step), steps a `Session` restored from it (the same
numbers as the process that wrote it: `services.sessions.codec`), and writes the new record over
the version it read (compare-and-set, `services.sessions.backends`). The answer leaves only
after the write: a replica killed between two steps loses nothing, and the next step on any
other process continues the same belief. Of two steps of one session racing on two processes
exactly one commits; the other gets `StepConflict` (409) and changes nothing. A step that fails
(bad input) writes nothing.

| rule        | what                                                                          |
|-------------|-------------------------------------------------------------------------------|
| ids         | 128 random bits and a tag of the deployment's secret: an id another          |
|             | deployment issued is `SessionNotFound` saying so, before any store access    |
| expiry      | as `SessionStore`: idle `ttl_s` (no step since), then gone; `get` does not    |
|             | extend it                                                                     |
| bounds      | `max_sessions` for the whole deployment, `max_per_client` per client address |
| records     | signed (`SessionCodec`): a record changed in the store, or of another format, |
|             | is `SessionStateInvalid` (410) for that session alone                         |
| store down  | `SessionStoreUnavailable` (503) naming the store and cause; no session lost  |
| local copy  | the sessions this process stepped last, by version (a bounded LRU): a step    |
|             | whose version is still the stored one reuses it, with the next step's         |
|             | evidence scored ahead (`Session.prepare_next`); another process recomputes it |

Settings are checked once per process per distinct settings (`check_settings`, cached by their
JSON): a session's settings never change over REST.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from services.engine import InferenceEngine
from services.sessions.backends import SessionBackend
from services.sessions.checks import CheckedSettings, check_settings
from services.sessions.codec import SessionCodec, settings_from_json, settings_json
from services.sessions.errors import (
    SessionLimitReached,
    SessionNotFound,
    SessionStateInvalid,
    StepConflict,
)
from services.sessions.messages import Observed, SessionInfo, SessionSettings, SessionStepResult
from services.sessions.session import Session

LOCAL_COPIES = 4096  # sessions a process keeps restored (each a few kB)
CHECKED_SETTINGS = 256  # distinct settings a process keeps checked


@dataclass
class _Copy:
    version: int
    session: Session
    client: str
    settings_json: bytes


class SharedSessionStore:
    """Sessions in a shared backend (module docstring); the interface of `SessionStore`."""

    def __init__(
        self,
        engine: InferenceEngine,
        backend: SessionBackend,
        codec: SessionCodec,
        *,
        max_sessions: int = 1000,
        max_per_client: int | None = None,
        ttl_s: float = 300.0,
        clock: Callable[[], float] = time.time,
        prefetch: bool = True,
        local_copies: int = LOCAL_COPIES,
    ) -> None:
        if max_sessions < 1:
            raise ValueError(f"max_sessions: expected >= 1, got {max_sessions}")
        if not ttl_s > 0:
            raise ValueError(f"ttl_s: expected > 0, got {ttl_s}")
        self.engine = engine
        self.backend = backend
        self.codec = codec
        self.max_sessions = max_sessions
        self.max_per_client = max_per_client or max_sessions
        self.ttl_s = ttl_s
        self.prefetch = prefetch
        self._clock = clock
        self._local_max = local_copies
        self._lock = threading.Lock()  # guards the two caches below
        self._copies: OrderedDict[str, _Copy] = OrderedDict()
        self._checked: OrderedDict[bytes, CheckedSettings] = OrderedDict()

    def __len__(self) -> int:
        """Live sessions of the deployment (a store round trip)."""
        return self.backend.count(self._clock())

    # --- operations ------------------------------------------------------------------------
    def create(self, settings: SessionSettings, client: str = "") -> SessionInfo:
        session_id = self.codec.new_id()
        session = Session(self.engine, settings, session_id, prefetch=self.prefetch)
        written = settings_json(session.settings)
        self._remember_checked(written, session)
        record = self.codec.encode(session_id, written, session.export_state())
        created = self.backend.create(
            session_id,
            client,
            record,
            self._clock(),
            self.ttl_s,
            self.max_sessions,
            self.max_per_client,
        )
        if created.outcome == "full":
            raise SessionLimitReached(self.max_sessions, created.retry_after_s)
        if created.outcome == "client_full":
            raise SessionLimitReached(self.max_per_client, created.retry_after_s, per_client=True)
        self._keep(session_id, _Copy(1, session, client, written))
        return self._info(session, self.ttl_s)

    def step(
        self,
        session_id: str,
        observation: object,
        observed: Sequence[Observed] = (),
        expected_step: int | None = None,
    ) -> SessionStepResult:
        """One step of the session (`Session.step`), committed to the store before it is
        answered; its idle time restarts."""
        copy, _ = self._current(session_id, take=True)  # this thread's own until kept again
        try:
            result = copy.session.step(observation, observed, expected_step)
        except BaseException:
            self._keep(session_id, copy)  # a failed step changes nothing
            raise
        record = self.codec.encode(session_id, copy.settings_json, copy.session.export_state())
        replaced = self.backend.replace(
            session_id, copy.version, record, copy.client, self._clock(), self.ttl_s
        )
        if replaced.outcome == "gone":
            raise SessionNotFound(session_id, self._gone_why())
        if replaced.outcome == "raced":
            raise StepConflict(session_id, result.step, result.step + 1, raced=True)
        copy.version = replaced.version
        self._keep(session_id, copy)
        return result

    def prepare_next(self, session_id: str) -> bool:
        """`Session.prepare_next` of this process's copy, if it still has one."""
        with self._lock:
            copy = self._copies.get(session_id)
        return copy is not None and copy.session.prepare_next()

    def settings(self, session_id: str) -> SessionSettings:
        """The session's settings: from this process's copy when it has one (they never change
        over REST), else read from the store."""
        self.codec.check_id(session_id)
        with self._lock:
            copy = self._copies.get(session_id)
        if copy is not None:
            return copy.session.settings
        return self._current(session_id, take=False)[0].session.settings

    def get(self, session_id: str) -> SessionInfo:
        copy, expires_at = self._current(session_id, take=False)
        return self._info(copy.session, expires_at - self._clock())

    def delete(self, session_id: str) -> None:
        copy, _ = self._current(session_id, take=True)
        if not self.backend.delete(session_id, copy.client):
            raise SessionNotFound(session_id, self._gone_why())

    def purge_expired(self) -> int:
        """Expired records vanish by themselves (Redis) or at the next create (PostgreSQL);
        the copies of this process are dropped by their LRU. Nothing to do here."""
        return 0

    # --- helpers ---------------------------------------------------------------------------
    def _current(self, session_id: str, *, take: bool) -> tuple[_Copy, float]:
        """The session at its stored version (this process's copy when it is that version,
        else restored from the record) and when it expires (wall clock). `take`: removed from
        the copies (the caller keeps it again when done), so two threads never step one
        object."""
        self.codec.check_id(session_id)
        with self._lock:
            copy = self._copies.pop(session_id, None) if take else self._copies.get(session_id)
        now = self._clock()
        loaded = self.backend.load(session_id, copy.version if copy is not None else 0, now)
        if loaded is None:
            self._forget(session_id)
            raise SessionNotFound(session_id, self._gone_why())
        if copy is not None and loaded.record is None:
            return copy, loaded.expires_at
        if loaded.record is None:  # a version 0 known: cannot happen (versions start at 1)
            raise SessionStateInvalid(session_id, "the store sent no record")
        written, state = self.codec.decode(session_id, loaded.record)
        checked = self._checked_settings(session_id, written)
        try:
            session = Session.restore(
                self.engine, checked, state, session_id, prefetch=self.prefetch
            )
        except ValueError as err:
            raise SessionStateInvalid(
                session_id, f"its stored state does not fit its settings: {err}"
            ) from None
        copy = _Copy(loaded.version, session, loaded.client, written)
        if not take:
            self._keep(session_id, copy)
        return copy, loaded.expires_at

    def _checked_settings(self, session_id: str, written: bytes) -> CheckedSettings:
        with self._lock:
            checked = self._checked.get(written)
            if checked is not None:
                self._checked.move_to_end(written)
                return checked
        try:
            settings = settings_from_json(written)
        except (ValueError, KeyError, TypeError) as err:
            raise SessionStateInvalid(
                session_id, f"its stored settings are unreadable: {err}"
            ) from None
        checked = check_settings(settings)  # the models' catalogue may have changed: checked again
        with self._lock:
            self._checked[written] = checked
            while len(self._checked) > CHECKED_SETTINGS:
                self._checked.popitem(last=False)
        return checked

    def _remember_checked(self, written: bytes, session: Session) -> None:
        with self._lock:
            self._checked[written] = session.checked
            while len(self._checked) > CHECKED_SETTINGS:
                self._checked.popitem(last=False)

    def _keep(self, session_id: str, copy: _Copy) -> None:
        with self._lock:
            self._copies[session_id] = copy
            self._copies.move_to_end(session_id)
            while len(self._copies) > self._local_max:
                self._copies.popitem(last=False)

    def _forget(self, session_id: str) -> None:
        with self._lock:
            self._copies.pop(session_id, None)

    def _gone_why(self) -> str:
        return f"it expired after {self.ttl_s:g} s idle, or was deleted"

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
