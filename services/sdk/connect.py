"""How the SDK's clients reach a server that wants a token, or speaks TLS.

| client                         | token                         | TLS                                   |
|--------------------------------|-------------------------------|---------------------------------------|
| `CoexistClient`, `AsyncCoexistClient`, `JobsClient` | `token=`: `Authorization: Bearer` on every request | an `https://` URL; `verify=` a CA file (a server's own certificate authority) or False |
| `GrpcCoexistClient`, `AsyncGrpcCoexistClient` | `token=`: `authorization: Bearer` metadata on every call (streams included) | `tls=True` or a `grpcs://` target; `root_certificates=` a CA file (default: the system's) |

The server side is `services.auth` (tokens) and the `COEXIST_TLS_*` settings (docs/security.md).
"""

from __future__ import annotations

import ssl
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import grpc

Verify = bool | str | Path
Metadata = tuple[tuple[str, str], ...] | None


def http_headers(token: str | None, headers: Mapping[str, str] | None) -> dict[str, str] | None:
    """`headers` plus the bearer token (None when there is neither)."""
    merged = dict(headers or {})
    if token:
        merged["Authorization"] = f"Bearer {token}"
    return merged or None


def http_verify(verify: Verify) -> bool | ssl.SSLContext:
    """httpx's `verify`: True (the system's CAs), False, or a context trusting a CA file."""
    if isinstance(verify, bool):
        return verify
    return ssl.create_default_context(cafile=str(verify))


def grpc_target(target: str) -> tuple[str, bool]:
    """(`host:port`, whether the target asked for TLS) of `host:port`, `grpc://host:port` or
    `grpcs://host:port`."""
    secure = target.startswith("grpcs://")
    return target.removeprefix("grpcs://").removeprefix("grpc://").rstrip("/"), secure


def grpc_metadata(token: str | None) -> Metadata:
    return (("authorization", f"Bearer {token}"),) if token else None


def grpc_channel(
    target: str,
    *,
    tls: bool,
    root_certificates: str | Path | None,
    options: list[tuple[str, Any]] | None,
    aio: bool = False,
) -> Any:
    """A channel to `target` (`grpc_target`'s forms): TLS when asked for by `tls`, the
    `grpcs://` scheme or a `root_certificates` file, else plain."""
    address, secure = grpc_target(target)
    if not (tls or secure or root_certificates is not None):
        return (grpc.aio if aio else grpc).insecure_channel(address, options=options)
    roots = Path(root_certificates).read_bytes() if root_certificates is not None else None
    credentials = grpc.ssl_channel_credentials(root_certificates=roots)
    return (grpc.aio if aio else grpc).secure_channel(address, credentials, options=options)
