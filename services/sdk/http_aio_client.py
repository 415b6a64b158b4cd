"""`AsyncCoexistClient`: the REST client on `httpx.AsyncClient`, the same methods as
`CoexistClient` (`http_client`), awaited.

    async with AsyncCoexistClient("http://127.0.0.1:8000") as client:
        a = await client.act("particle", "a2", obs, partners={1: "b3"})
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import httpx
from numpy.typing import ArrayLike

from services.sdk.bodies import Partners, act_batch_body, act_body, session_body
from services.sdk.connect import Verify, http_headers, http_verify
from services.sdk.errors import CoexistError
from services.sdk.http_client import DEFAULT_URL, checked_json, envs_from_json, unavailable_error
from services.sdk.http_sessions import AsyncSession, new_affinity
from services.sdk.types import Action, ActionColumns, EnvInfo, Health, SessionInfo, async_rows_of


class AsyncCoexistClient:
    """Asynchronous client of the REST API (httpx.AsyncClient); the same methods, awaited."""

    def __init__(
        self,
        base_url: str = DEFAULT_URL,
        *,
        timeout: float = 10.0,
        headers: dict[str, str] | None = None,
        transport: httpx.AsyncBaseTransport | None = None,
        token: str | None = None,
        verify: Verify = True,
    ) -> None:
        self._http = httpx.AsyncClient(
            base_url=base_url, timeout=timeout, headers=http_headers(token, headers),
            transport=transport, verify=http_verify(verify),
        )  # fmt: skip

    async def _request(
        self, method: str, path: str, body: Any = None, headers: dict[str, str] | None = None
    ) -> Any:
        try:
            response = await self._http.request(method, path, json=body, headers=headers)
        except httpx.TransportError as err:
            raise unavailable_error(err) from err
        return checked_json(response)

    async def act(
        self,
        env: str,
        ego_goal: str,
        observation: ArrayLike | None = None,
        *,
        state: ArrayLike | None = None,
        ego_index: int = 0,
        partners: Partners = None,
        method: str = "aail_bounded",
        temperature: float | None = None,
        regret_bound: float | None = None,
        seed: int | None = None,
        alias: str = "production",
        versions: Mapping[str, int] | None = None,
    ) -> Action:
        body = act_body(
            env,
            ego_goal,
            observation,
            state=state,
            ego_index=ego_index,
            partners=partners,
            method=method,
            temperature=temperature,
            regret_bound=regret_bound,
            seed=seed,
            alias=alias,
            versions=versions,
        )
        return Action.from_json(await self._request("POST", "/v1/act", body))

    async def act_batch_columns(
        self,
        env: str,
        ego_goal: str,
        observations: ArrayLike | None = None,
        *,
        states: ArrayLike | None = None,
        ego_index: int = 0,
        partners: Partners = None,
        method: str = "aail_bounded",
        temperature: float | None = None,
        regret_bound: float | None = None,
        seed: int | None = None,
        alias: str = "production",
        versions: Mapping[str, int] | None = None,
    ) -> ActionColumns:
        body = act_batch_body(
            env, ego_goal, observations, states=states, ego_index=ego_index, partners=partners,
            method=method, temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias, versions=versions,
            columns=True,
        )  # fmt: skip
        return await self._columns(body)

    act_batch = async_rows_of(act_batch_columns)

    async def _columns(self, body: dict[str, Any]) -> ActionColumns:
        return ActionColumns.from_json(await self._request("POST", "/v1/act:batch", body))

    async def envs(self) -> list[EnvInfo]:
        return envs_from_json(await self._request("GET", "/v1/envs"))

    async def health(self) -> Health:
        live = await self._request("GET", "/healthz")
        try:
            ready, detail = True, await self._request("GET", "/readyz")
        except CoexistError as err:
            ready, detail = False, {"code": err.code, "message": err.message}
        return Health(live=bool(live), ready=ready, detail=detail or {})

    async def create_session(
        self,
        env: str,
        ego_goal: str,
        *,
        partners: Partners = None,
        infer: Sequence[int] = (),
        method: str = "aail_bounded",
        temperature: float | None = None,
        regret_bound: float | None = None,
        seed: int | None = None,
        alias: str = "production",
        versions: Mapping[str, int] | None = None,
        belief: Mapping[str, Any] | None = None,
        expect_steps: bool = True,
    ) -> AsyncSession:
        """As `CoexistClient.create_session`, awaited."""
        body = session_body(
            env, ego_goal, partners=partners, infer=infer, method=method,
            temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias, versions=versions, belief=belief,
        )  # fmt: skip
        headers = new_affinity()
        info = SessionInfo.from_json(await self._request("POST", "/v1/sessions", body, headers))
        return AsyncSession(self._request, info, headers, expect_steps=expect_steps)

    async def aclose(self) -> None:
        await self._http.aclose()

    async def __aenter__(self) -> AsyncCoexistClient:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.aclose()
