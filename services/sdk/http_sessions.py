"""REST sessions in the SDK: `Session` (sync, from `CoexistClient.create_session`) and
`AsyncSession` (from `AsyncCoexistClient.create_session`).

    with client.create_session("particle", "a2", partners={1: None}, seed=0) as session:
        first = session.step(obs_0)                          # SessionStep: an Action + beliefs
        later = session.step(obs_1, observed={1: 3})         # partner 1 took action 3 since
        later.beliefs[0].goal, later.beliefs[0].top          # the belief over its goal

| method                     | route                              | returns        |
|----------------------------|------------------------------------|----------------|
| `step(obs, observed=...)`  | `POST /v1/sessions/{id}/steps`     | `SessionStep`  |
| `info()`                   | `GET /v1/sessions/{id}`            | `SessionInfo`  |
| `close()`                  | `DELETE /v1/sessions/{id}`         | (already gone: no error) |

Every request of a session carries the header `X-Coexist-Affinity` with a random key made at
creation: a load balancer hashing on it (docs/architecture.md, "Sessions") sends all of a
session's requests to the replica that holds it. `expected_step` is sent automatically
(`expect_steps=True`), so a retried step never counts twice: a conflict raises `Conflict`.
"""

from __future__ import annotations

import contextlib
import secrets
from collections.abc import Awaitable, Callable
from typing import Any

from services.sdk.bodies import Observed, step_body
from services.sdk.errors import NotFound
from services.sdk.types import SessionInfo, SessionStep

AFFINITY_HEADER = "X-Coexist-Affinity"

SyncRequest = Callable[[str, str, Any, dict[str, str]], Any]
AsyncRequest = Callable[[str, str, Any, dict[str, str]], Awaitable[Any]]


def new_affinity() -> dict[str, str]:
    return {AFFINITY_HEADER: secrets.token_urlsafe(12)}


class _SessionBase:
    def __init__(self, info: SessionInfo, headers: dict[str, str], expect_steps: bool) -> None:
        self.session_id = info.session_id
        self.created = info
        self.headers = headers
        self.expect_steps = expect_steps
        self.next_step = info.step  # the index the next step gets, as this client knows it
        self.path = f"/v1/sessions/{info.session_id}"

    def _body(self, observation: Any, state: Any, ego_index: int, observed: Observed) -> Any:
        expected = self.next_step if self.expect_steps else None
        return step_body(
            observation, state=state, ego_index=ego_index, observed=observed,
            expected_step=expected,
        )  # fmt: skip


class Session(_SessionBase):
    """One REST session (sync); see the module docstring."""

    def __init__(
        self, request: SyncRequest, info: SessionInfo, headers: dict[str, str], *,
        expect_steps: bool = True,
    ) -> None:  # fmt: skip
        super().__init__(info, headers, expect_steps)
        self._request = request

    def step(
        self,
        observation: Any = None,
        *,
        state: Any = None,
        ego_index: int = 0,
        observed: Observed = None,
    ) -> SessionStep:
        """One step: `observed` = the inferred partners' actions since the previous step."""
        body = self._body(observation, state, ego_index, observed)
        answer = SessionStep.from_json(
            self._request("POST", f"{self.path}/steps", body, self.headers)
        )
        self.next_step = answer.step + 1
        return answer

    def info(self) -> SessionInfo:
        return SessionInfo.from_json(self._request("GET", self.path, None, self.headers))

    def close(self) -> None:
        """Delete the session on the server (nothing happens if it is already gone)."""
        with contextlib.suppress(NotFound):
            self._request("DELETE", self.path, None, self.headers)

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


class AsyncSession(_SessionBase):
    """One REST session (async); the same methods, awaited."""

    def __init__(
        self, request: AsyncRequest, info: SessionInfo, headers: dict[str, str], *,
        expect_steps: bool = True,
    ) -> None:  # fmt: skip
        super().__init__(info, headers, expect_steps)
        self._request = request

    async def step(
        self,
        observation: Any = None,
        *,
        state: Any = None,
        ego_index: int = 0,
        observed: Observed = None,
    ) -> SessionStep:
        body = self._body(observation, state, ego_index, observed)
        data = await self._request("POST", f"{self.path}/steps", body, self.headers)
        answer = SessionStep.from_json(data)
        self.next_step = answer.step + 1
        return answer

    async def info(self) -> SessionInfo:
        return SessionInfo.from_json(await self._request("GET", self.path, None, self.headers))

    async def aclose(self) -> None:
        with contextlib.suppress(NotFound):
            await self._request("DELETE", self.path, None, self.headers)

    async def __aenter__(self) -> AsyncSession:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.aclose()
