"""A session as bytes: its settings and state (`SessionState`), signed, without pickle.

    codec = SessionCodec(secret)
    session_id = codec.new_id()                        # random, tagged by this deployment
    codec.check_id(session_id)                         # SessionNotFound: another deployment's
    record = codec.encode(session_id, settings, state)
    settings_json, settings, state = codec.decode(session_id, record)  # SessionStateInvalid

A record is `FORMAT` (3 bytes), an HMAC-SHA256 tag (32 bytes) over the session id and all that
follows, the settings' length (4 bytes, big-endian), the settings as JSON, the state as JSON.
Arrays are `{"dtype", "shape", "data": base64 of the raw little-endian bytes}` and JSON floats
round-trip exactly (orjson writes the shortest repr), so a decoded session answers bit for bit
as the encoded one would. The settings' JSON bytes are kept apart so that a server checks each
distinct settings once (`services.sessions.shared` caches `check_settings` by them).

The secret (`COEXIST_SESSION_SECRET`, shared by every replica of a deployment) signs both the
ids and the records: a record changed outside the servers, moved to another session id, or
written by another deployment fails its tag; an id another deployment issued fails its own. A
record of another `FORMAT` (an older or newer server) is refused by name, never misread.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import secrets
import struct
from collections.abc import Mapping
from typing import Any

import numpy as np
import orjson

from model_store.errors import brief
from policy.belief import BeliefConfig
from services.sessions.errors import SessionNotFound, SessionStateInvalid
from services.sessions.messages import SessionPartner, SessionSettings, SessionState

FORMAT = b"CS4"  # bump when the layout or a field's meaning changes
TAG_BYTES = 32
ID_TAG_CHARS = 11  # 66 bits of the id's HMAC: a foreign or mistyped id is told apart
DTYPES: dict[str, np.dtype[Any]] = {"float64": np.dtype("<f8"), "float32": np.dtype("<f4")}


class SessionCodec:
    """Ids and records of one deployment (module docstring)."""

    def __init__(self, secret: bytes) -> None:
        if not secret:
            raise ValueError("secret: expected a non-empty secret")
        self._secret = secret

    def namespace(self) -> str:
        """A name for this deployment's keys in a shared store, derived from the secret (so
        two deployments on one store never count or see each other's sessions)."""
        return hmac.new(self._secret, b"coexist-session-namespace", hashlib.sha256).hexdigest()[:16]

    # --- ids ---------------------------------------------------------------------------------
    def new_id(self) -> str:
        token = secrets.token_urlsafe(16)  # 128 random bits
        return f"{token}.{self._id_tag(token)}"

    def check_id(self, session_id: object) -> str:
        """The id if this deployment issued it, else `SessionNotFound` saying so."""
        if isinstance(session_id, str):
            token, dot, tag = session_id.partition(".")
            if dot and hmac.compare_digest(tag, self._id_tag(token)):
                return session_id
        raise SessionNotFound(
            str(session_id),
            "this deployment did not issue it (a session id from another deployment, or one "
            "mistyped: its tag does not match this deployment's COEXIST_SESSION_SECRET)",
        )

    def _id_tag(self, token: str) -> str:
        mac = hmac.new(self._secret, b"id:" + token.encode(), hashlib.sha256).digest()
        return base64.urlsafe_b64encode(mac).decode()[:ID_TAG_CHARS]

    # --- records -----------------------------------------------------------------------------
    def encode(self, session_id: str, settings_json: bytes, state: SessionState) -> bytes:
        body = struct.pack(">I", len(settings_json)) + settings_json + orjson.dumps(_state(state))
        return FORMAT + self._tag(session_id, body) + body

    def decode(self, session_id: str, record: bytes) -> tuple[bytes, SessionState]:
        """The settings' JSON and the state; `SessionStateInvalid` naming what is wrong."""
        head = record[: len(FORMAT)]
        if head != FORMAT:
            raise SessionStateInvalid(
                session_id,
                f"its stored state has format {brief(head.decode(errors='replace'))}, this "
                f"server reads {FORMAT.decode()} (written by another server version)",
            )
        tag, body = record[len(FORMAT) : len(FORMAT) + TAG_BYTES], record[len(FORMAT) + TAG_BYTES :]
        if not hmac.compare_digest(tag, self._tag(session_id, body)):
            raise SessionStateInvalid(
                session_id,
                "its stored state failed its integrity check (changed outside this deployment's "
                "servers, or signed with another COEXIST_SESSION_SECRET)",
            )
        try:  # signed by this deployment: a failure here is a server bug, still named
            (length,) = struct.unpack(">I", body[:4])
            settings_json = body[4 : 4 + length]
            return settings_json, _state_from(orjson.loads(body[4 + length :]))
        except (ValueError, KeyError, IndexError, TypeError, struct.error) as err:
            raise SessionStateInvalid(
                session_id, f"its stored state is unreadable: {err}"
            ) from None

    def _tag(self, session_id: str, body: bytes) -> bytes:
        mac = hmac.new(self._secret, session_id.encode() + b"\0", hashlib.sha256)
        mac.update(body)
        return mac.digest()


# --- settings ----------------------------------------------------------------------------------
def settings_json(settings: SessionSettings) -> bytes:
    """The settings as JSON, fields in a fixed order (equal settings, equal bytes)."""
    return orjson.dumps(
        {
            "env": settings.env,
            "ego_goal": settings.ego_goal,
            "partners": [
                [
                    p.index,
                    p.goal,
                    None if p.goal_probs is None else dict(p.goal_probs),
                    p.infer,
                ]
                for p in settings.partners
            ],
            "method": settings.method,
            "temperature": settings.temperature,
            "regret_bound": settings.regret_bound,
            "budget": settings.budget,
            "seed": settings.seed,
            "alias": settings.alias,
            "versions": dict(settings.versions),
            "belief": [
                settings.belief.forgetting,
                settings.belief.floor,
                settings.belief.temperature,
                settings.belief.noise,
                settings.belief.prune_below,
                settings.belief.prune_error,
            ],
            "blend_mass": settings.blend_mass,
            "blend_max_goals": settings.blend_max_goals,
        }
    )


def settings_from_json(data: bytes) -> SessionSettings:
    d = orjson.loads(data)
    forgetting, floor, temperature, noise, prune_below, prune_error = d["belief"]
    return SessionSettings(
        env=d["env"],
        ego_goal=d["ego_goal"],
        partners=tuple(
            SessionPartner(index, goal, probs, infer) for index, goal, probs, infer in d["partners"]
        ),
        method=d["method"],
        temperature=d["temperature"],
        regret_bound=d["regret_bound"],
        budget=d["budget"],
        seed=d["seed"],
        alias=d["alias"],
        versions=d["versions"],
        belief=BeliefConfig(
            forgetting=forgetting,
            floor=floor,
            temperature=temperature,
            noise=noise,
            prune_below=prune_below,
            prune_error=prune_error,
        ),
        blend_mass=d["blend_mass"],
        blend_max_goals=d["blend_max_goals"],
    )


# --- state -------------------------------------------------------------------------------------
def _array(a: np.ndarray) -> dict[str, Any]:
    name = {v: k for k, v in DTYPES.items()}[a.dtype.newbyteorder("<")]
    return {
        "dtype": name,
        "shape": list(a.shape),
        "data": base64.b64encode(
            np.ascontiguousarray(a, a.dtype.newbyteorder("<")).tobytes()
        ).decode(),
    }


def _array_from(d: Mapping[str, Any]) -> np.ndarray:
    dtype = DTYPES.get(d["dtype"])
    if dtype is None:
        raise ValueError(f"dtype: expected one of {sorted(DTYPES)}, got {brief(d['dtype'])}")
    shape = tuple(int(n) for n in d["shape"])
    raw = base64.b64decode(d["data"], validate=True)
    if len(raw) != dtype.itemsize * int(np.prod(shape)):
        raise ValueError(f"data: {len(raw)} bytes do not hold {dtype} {shape}")
    return np.frombuffer(raw, dtype).reshape(shape).astype(dtype.newbyteorder("="))


def _state(state: SessionState) -> dict[str, Any]:
    return {
        "first_step": state.first_step,
        "next_step": state.next_step,
        "log_belief": _array(state.log_belief_PG),
        "updates": list(state.updates),
        "last_actions": list(state.last_actions),
        "previous": None if state.previous is None else _array(state.previous),
        "previous_agents": state.previous_agents,
        "budget": None if state.budget is None else list(state.budget),
        "table_partners": list(state.table_partners),
    }


def _state_from(d: Mapping[str, Any]) -> SessionState:
    budget = d["budget"]
    return SessionState(
        first_step=int(d["first_step"]),
        next_step=int(d["next_step"]),
        log_belief_PG=_array_from(d["log_belief"]),
        updates=tuple(int(n) for n in d["updates"]),
        last_actions=tuple(None if a is None else int(a) for a in d["last_actions"]),
        previous=None if d["previous"] is None else _array_from(d["previous"]),
        previous_agents=int(d["previous_agents"]),
        budget=None if budget is None else (float(budget[0]), float(budget[1]), float(budget[2])),
        table_partners=tuple(int(i) for i in d["table_partners"]),
    )
