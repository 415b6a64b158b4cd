"""FastAPI dependencies shared by the routers: the store, the settings, and bearer-token auth.

| alias         | gives          | fails with                                               |
|---------------|----------------|----------------------------------------------------------|
| `StoreDep`    | the ModelStore | 503 when the store is not open                           |
| `SettingsDep` | the Settings   |                                                          |
| `WriteAuth`   | nothing        | 401 without a bearer token, 403 with a wrong one         |
| `ReadAuth`    | nothing        | the same, only when reads need a token (see settings.py) |

Tokens are compared in constant time (`services.auth.token_matches`) so response timing does
not leak how much of a guess was right. When reads need a token, `services.auth.TokenGate` also
guards every route before it is reached (inference, sessions, metrics, docs).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from model_store.errors import StoreUnavailable
from model_store.store import ModelStore
from services.auth import token_matches
from services.registry.errors import ApiError
from services.settings import Settings

_bearer = HTTPBearer(auto_error=False, description="COEXIST_ADMIN_TOKEN (writes) or read token")


def get_app_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


def get_store(request: Request) -> ModelStore:
    store: ModelStore | None = getattr(request.app.state, "store", None)
    if store is None:
        raise StoreUnavailable("the model store is not open (the server is starting or stopping)")
    return store


SettingsDep = Annotated[Settings, Depends(get_app_settings)]
StoreDep = Annotated[ModelStore, Depends(get_store)]
Credentials = Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]


def _check(credentials: HTTPAuthorizationCredentials | None, *accepted: str | None) -> None:
    if credentials is None or not credentials.credentials:
        raise ApiError(
            401,
            "unauthorized",
            "this endpoint needs 'Authorization: Bearer <token>'",
            headers={"WWW-Authenticate": "Bearer"},
        )
    if not token_matches(credentials.credentials, *accepted):
        raise ApiError(403, "forbidden", "the bearer token is not valid for this endpoint")


def require_write(settings: SettingsDep, credentials: Credentials) -> None:
    _check(credentials, settings.admin_token.get_secret_value())


def require_read(settings: SettingsDep, credentials: Credentials) -> None:
    if not settings.reads_need_token:
        return
    read = settings.read_token.get_secret_value() if settings.read_token else None
    _check(credentials, read, settings.admin_token.get_secret_value())


WriteAuth = Annotated[None, Depends(require_write)]
ReadAuth = Annotated[None, Depends(require_read)]
