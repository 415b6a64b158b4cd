"""HTTP client of the coexist REST API (httpx): `CoexistClient` (sync; `AsyncCoexistClient` in
`http_aio_client`).

    with CoexistClient("http://127.0.0.1:8000") as client:
        a = client.act("particle", "a2", obs, partners={1: "b3"}, seed=7)
        a.action, a.probs, a.diagnostics.task_weight

| method                  | route                   | returns          |
|-------------------------|-------------------------|------------------|
| `act(...)`              | `POST /v1/act`          | `Action`         |
| `act_batch(...)`        | `POST /v1/act:batch`    | `list[Action]`   |
| `act_batch_columns(...)`| `POST /v1/act:batch`    | `ActionColumns`  |
| `envs()`                | `GET /v1/envs`          | `list[EnvInfo]`  |
| `health()`              | `/healthz`, `/readyz`   | `Health`         |
| `episode(...)`          | `POST /v1/act` per step | an episode session |
| `create_session(...)`   | `POST /v1/sessions`     | `Session` (goals inferred online; `http_sessions`) |

An episode session follows the gRPC `Episode` stream's rules over plain requests: the settings are
given once, and step t samples with seed + t, so both transports give the same episode.
Errors raise `services.sdk.errors` classes (`InvalidArgument`, `NotFound`, `Unavailable`).
`token=` sends `Authorization: Bearer <token>` with every request; an `https://` URL speaks TLS,
`verify=` naming the CA file of a server's own certificate authority (`services.sdk.connect`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import httpx
from numpy.typing import ArrayLike

from services.sdk.bodies import (
    Partners,
    act_batch_body,
    act_body,
    episode_settings,
    session_body,
    step_seed,
)
from services.sdk.connect import Verify, http_headers, http_verify
from services.sdk.errors import CoexistError, Unavailable, error_for_http
from services.sdk.http_sessions import Session, new_affinity
from services.sdk.types import Action, ActionColumns, EnvInfo, Health, SessionInfo, rows_of

DEFAULT_URL = "http://127.0.0.1:8000"


def checked_json(response: httpx.Response) -> Any:
    """The response's JSON, or the SDK error its error body describes."""
    if response.status_code < 400:
        return response.json() if response.content else None  # 204: no body
    try:
        error = response.json()["error"]
        message, field = str(error["message"]), error.get("field")
    except (ValueError, KeyError, TypeError):
        message, field = f"HTTP {response.status_code}: {response.text[:500]}", None
    raise error_for_http(response.status_code, message, field)


def unavailable_error(err: httpx.TransportError) -> Unavailable:
    return Unavailable("unavailable", f"{type(err).__name__}: {err}")


def envs_from_json(data: Any) -> list[EnvInfo]:
    items = data["envs"] if isinstance(data, dict) else data
    return [EnvInfo.from_json(e) for e in items]


class CoexistClient:
    """Synchronous client of the REST API; see the module docstring."""

    def __init__(
        self,
        base_url: str = DEFAULT_URL,
        *,
        timeout: float = 10.0,
        headers: dict[str, str] | None = None,
        transport: httpx.BaseTransport | None = None,
        token: str | None = None,
        verify: Verify = True,
    ) -> None:
        self._http = httpx.Client(
            base_url=base_url, timeout=timeout, headers=http_headers(token, headers),
            transport=transport, verify=http_verify(verify),
        )  # fmt: skip

    def _request(
        self, method: str, path: str, body: Any = None, headers: dict[str, str] | None = None
    ) -> Any:
        try:
            response = self._http.request(method, path, json=body, headers=headers)
        except httpx.TransportError as err:
            raise unavailable_error(err) from err
        return checked_json(response)

    def act(
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
        """One action for one observation (or state + ego_index)."""
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
        return Action.from_json(self._request("POST", "/v1/act", body))

    def act_batch_columns(
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
        """`act_batch`'s answer as arrays, one per field (the server's columnar format)."""
        body = act_batch_body(
            env, ego_goal, observations, states=states, ego_index=ego_index, partners=partners,
            method=method, temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias, versions=versions,
            columns=True,
        )  # fmt: skip
        return self._columns(body)

    act_batch = rows_of(act_batch_columns)

    def _columns(self, body: dict[str, Any]) -> ActionColumns:
        return ActionColumns.from_json(self._request("POST", "/v1/act:batch", body))

    def envs(self) -> list[EnvInfo]:
        return envs_from_json(self._request("GET", "/v1/envs"))

    def health(self) -> Health:
        """Liveness (`/healthz`) and readiness (`/readyz`; not ready on 503)."""
        live = self._request("GET", "/healthz")
        try:
            ready, detail = True, self._request("GET", "/readyz")
        except CoexistError as err:
            ready, detail = False, {"code": err.code, "message": err.message}
        return Health(live=bool(live), ready=ready, detail=detail or {})

    def episode(
        self,
        env: str,
        ego_goal: str,
        *,
        partners: Partners = None,
        method: str = "aail_bounded",
        temperature: float | None = None,
        regret_bound: float | None = None,
        seed: int | None = None,
        alias: str = "production",
        versions: Mapping[str, int] | None = None,
    ) -> HttpEpisode:
        """A session for one episode: settings given once, then `session.act(obs)` per step."""
        settings = episode_settings(
            env, ego_goal, partners=partners, method=method, temperature=temperature, regret_bound=regret_bound,
            seed=seed, alias=alias, versions=versions,
        )  # fmt: skip
        return HttpEpisode(self, settings)

    def create_session(
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
    ) -> Session:
        """A REST session whose partners' goals the server infers from their actions:
        `partners={1: None}` (uniform prior) or `infer=[1]` (the announced goal is the prior)."""
        body = session_body(
            env, ego_goal, partners=partners, infer=infer, method=method,
            temperature=temperature, regret_bound=regret_bound, seed=seed, alias=alias, versions=versions, belief=belief,
        )  # fmt: skip
        headers = new_affinity()
        info = SessionInfo.from_json(self._request("POST", "/v1/sessions", body, headers))
        return Session(self._request, info, headers, expect_steps=expect_steps)

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> CoexistClient:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


class HttpEpisode:
    """One episode over `POST /v1/act`: fixed settings, step t seeded with seed + t."""

    def __init__(self, client: CoexistClient, settings: dict[str, Any]) -> None:
        self._client = client
        self._settings = settings
        self.step = 0

    def act(self, observation: Any = None, *, state: Any = None, ego_index: int = 0) -> Action:
        s = self._settings
        action = self._client.act(
            s["env"], s["ego_goal"], observation, state=state, ego_index=ego_index,
            partners=s["partners"], method=s["method"], temperature=s["temperature"],
            regret_bound=s["regret_bound"], seed=step_seed(s["seed"], self.step),
            alias=s["alias"], versions=s["versions"],
        )  # fmt: skip
        self.step += 1
        return action

    def close(self) -> None:
        """Nothing to release (each step is its own request)."""

    def __enter__(self) -> HttpEpisode:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
