"""`RegistryClient` (sync) and `AsyncRegistryClient`: the server's model registry over HTTP.

    with RegistryClient("http://127.0.0.1:8000", token=os.environ["COEXIST_ADMIN_TOKEN"]) as reg:
        reg.list(kind="task")                                   # one page of ModelInfo
        reg.show("particle/task/a2").versions[0].lineage        # a model with its versions
        v = reg.upload("particle/task/a2", spec, weights)       # a new version (VersionInfo)
        reg.promote("particle/task/a2", v.version)              # alias `production` -> it
        data = reg.download("particle/task/a2", v.version)      # bytes, sha256 checked

| method                                  | route (under `/v1/registry`)              | returns        |
|-----------------------------------------|-------------------------------------------|----------------|
| `list(env=, kind=, goal=, tag=, ...)`   | `GET /models`                             | `ModelPage`    |
| `show(name)`                            | `GET /models/{name}`                      | `ModelInfo` (with versions) |
| `create_model(name, env=, kind=, ...)` | `POST /models`                           | `ModelInfo`    |
| `version(name, version)`                | `GET /models/{name}/-/versions/{v}`       | `VersionInfo`  |
| `resolve(ref)`                          | `GET /resolve?ref=name@alias`             | `VersionInfo`  |
| `upload(name, spec, weights, ...)`      | `POST /models/{name}/-/versions` (multipart) | `VersionInfo` |
| `promote(name, version, alias=)`        | `PUT /models/{name}/-/aliases/{alias}`    | `int` (the version) |
| `archive(name, version)`                | `POST /models/{name}/-/versions/{v}/archive` | `VersionInfo` |
| `download(name, version)`               | `GET /models/{name}/-/versions/{v}/weights` | `bytes` (safetensors) |

Reads need the read token where the server has one, writes the admin token. `download` checks
the bytes against the server's `X-Checksum-Sha256` and the version's recorded sha256 and raises
`ChecksumMismatch` otherwise. `upload` sends an `Idempotency-Key` (the weights' sha256 unless one
is given), so it is retried safely after a lost answer.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import quote

from coexist_client.errors import CoexistError
from coexist_client.exchange import AsyncClosing, Closing, Core, Plan, awaiting, blocking
from coexist_client.transport import Http, HttpTransport, Raw

DEFAULT_URL = "http://127.0.0.1:8000"
PREFIX = "/v1/registry"


class ChecksumMismatch(CoexistError):
    """Downloaded weights whose sha256 is not the one the registry recorded."""


@dataclass(frozen=True)
class VersionInfo:
    """One registered version: its architecture spec, checksum, status and lineage (JSON)."""

    name: str
    version: int
    sha256: str
    size_bytes: int
    status: str
    spec: Mapping[str, Any] = field(default_factory=dict)
    lineage: Mapping[str, Any] = field(default_factory=dict)
    created_at: str = ""

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> VersionInfo:
        return cls(
            name=str(data["name"]),
            version=int(data["version"]),
            sha256=str(data["sha256"]),
            size_bytes=int(data.get("size_bytes", 0)),
            status=str(data.get("status", "")),
            spec=dict(data.get("spec") or {}),
            lineage=dict(data.get("lineage") or {}),
            created_at=str(data.get("created_at", "")),
        )


@dataclass(frozen=True)
class ModelInfo:
    """A registered model: what it is for, its aliases and (from `show`) its versions."""

    name: str
    env: str
    kind: str
    goals: tuple[str, ...]
    aliases: Mapping[str, int] = field(default_factory=dict)
    description: str = ""
    tags: Mapping[str, str] = field(default_factory=dict)
    obs_dim: int = 0
    n_actions: int = 0
    versions: tuple[VersionInfo, ...] = ()  # newest first; empty in a listing
    created_at: str = ""  # ISO 8601, as the server wrote it
    updated_at: str = ""

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ModelInfo:
        return cls(
            name=str(data["name"]),
            env=str(data["env"]),
            kind=str(data["kind"]),
            goals=tuple(data.get("goals", ())),
            aliases={str(k): int(v) for k, v in (data.get("aliases") or {}).items()},
            description=str(data.get("description", "")),
            tags=dict(data.get("tags") or {}),
            obs_dim=int(data.get("obs_dim", 0)),
            n_actions=int(data.get("n_actions", 0)),
            versions=tuple(VersionInfo.from_json(v) for v in data.get("versions", ())),
            created_at=str(data.get("created_at", "")),
            updated_at=str(data.get("updated_at", "")),
        )


@dataclass(frozen=True)
class ModelPage:
    models: tuple[ModelInfo, ...]
    next_page_token: str | None = None  # pass as `page_token` for the next page


def _model(name: str) -> str:
    return f"{PREFIX}/models/{quote(name, safe='/')}"


class RegistryCore(Core):
    def __init__(self, base_url: str = DEFAULT_URL, *, aio: bool = False, **options: Any) -> None:
        """`options`: `HttpTransport`'s (token, timeout, headers, verify, transport, retry)."""
        self.transport = HttpTransport(base_url, aio=aio, **options)


def list_models(
    core: RegistryCore,
    *,
    env: str | None = None,
    kind: str | None = None,
    goal: str | None = None,
    tag: str | None = None,
    page_size: int = 50,
    page_token: str | None = None,
) -> Plan[ModelPage]:
    """One page of models, filtered by env, kind (task, impact, joint, monitor), goal or tag."""
    wanted = {"env": env, "kind": kind, "goal": goal, "tag": tag, "page_token": page_token}
    params: dict[str, Any] = {k: v for k, v in wanted.items() if v is not None}
    params["page_size"] = page_size
    data = yield Http("GET", f"{PREFIX}/models", params=params)
    models = tuple(ModelInfo.from_json(m) for m in data["models"])
    return ModelPage(models, data.get("next_page_token"))


def show(core: RegistryCore, name: str) -> Plan[ModelInfo]:
    """A model with all its versions (newest first) and their lineage."""
    return ModelInfo.from_json((yield Http("GET", _model(name))))


def create_model(
    core: RegistryCore,
    name: str,
    *,
    env: str,
    kind: str,
    goals: Sequence[str],
    obs_dim: int,
    n_actions: int,
    description: str = "",
    tags: Mapping[str, str] | None = None,
) -> Plan[ModelInfo]:
    """Register a new model (no versions yet): what it is for and its sizes."""
    body = {
        "name": name,
        "env": env,
        "kind": kind,
        "goals": list(goals),
        "obs_dim": obs_dim,
        "n_actions": n_actions,
        "description": description,
        "tags": dict(tags or {}),
    }
    return ModelInfo.from_json((yield Http("POST", f"{PREFIX}/models", body, idempotent=False)))


def version(core: RegistryCore, name: str, version: int) -> Plan[VersionInfo]:
    """One version's metadata."""
    return VersionInfo.from_json((yield Http("GET", f"{_model(name)}/-/versions/{version}")))


def resolve(core: RegistryCore, ref: str) -> Plan[VersionInfo]:
    """The version `name@alias`, `name/3` or `name` (= @production) points at."""
    return VersionInfo.from_json((yield Http("GET", f"{PREFIX}/resolve", params={"ref": ref})))


def upload(
    core: RegistryCore,
    name: str,
    spec: Mapping[str, Any],
    weights: bytes,
    *,
    lineage: Mapping[str, Any] | None = None,
    aliases: Sequence[str] = (),
    idempotency_key: str | None = None,
) -> Plan[VersionInfo]:
    """Register a new version from an architecture spec and safetensors bytes; `latest` and
    `aliases` then point at it."""
    files: dict[str, Any] = {
        "spec": (None, json.dumps(dict(spec)), "application/json"),
        "weights": ("weights.safetensors", bytes(weights), "application/octet-stream"),
    }
    if lineage is not None:
        files["lineage"] = (None, json.dumps(dict(lineage)), "application/json")
    key = idempotency_key or hashlib.sha256(weights).hexdigest()
    data = yield Http(
        "POST",
        f"{_model(name)}/-/versions",
        params={"alias": list(aliases)},
        headers={"Idempotency-Key": key},
        files=files,
    )
    return VersionInfo.from_json(data)


def promote(core: RegistryCore, name: str, version: int, alias: str = "production") -> Plan[int]:
    """Point `alias` at `version` (atomically; servers pick it up within their refresh time)."""
    path = f"{_model(name)}/-/aliases/{quote(alias, safe='')}"
    data = yield Http("PUT", path, {"version": version})
    return int(data["version"])


def archive(core: RegistryCore, name: str, version: int) -> Plan[VersionInfo]:
    """Archive a version (kept; refused while an alias points at it)."""
    path = f"{_model(name)}/-/versions/{version}/archive"
    return VersionInfo.from_json((yield Http("POST", path)))


def download(core: RegistryCore, name: str, version: int) -> Plan[bytes]:
    """A version's safetensors bytes, checked against the registry's sha256."""
    meta = VersionInfo.from_json((yield Http("GET", f"{_model(name)}/-/versions/{version}")))
    raw: Raw = yield Http("GET", f"{_model(name)}/-/versions/{version}/weights", raw=True)
    digest = hashlib.sha256(raw.content).hexdigest()
    announced = raw.headers.get("x-checksum-sha256", digest)
    if digest != meta.sha256 or digest != announced:
        raise ChecksumMismatch(
            "data_loss", f"{name} v{version}: sha256 {digest} is not the recorded {meta.sha256}"
        )
    return raw.content


class RegistryClient(RegistryCore, Closing):
    """Synchronous registry client; see the module docstring."""

    list = blocking(list_models)
    show = blocking(show)
    create_model = blocking(create_model)
    version = blocking(version)
    resolve = blocking(resolve)
    upload = blocking(upload)
    promote = blocking(promote)
    archive = blocking(archive)
    download = blocking(download)


class AsyncRegistryClient(RegistryCore, AsyncClosing):
    """The registry client, awaited (`aclose()` to close)."""

    def __init__(self, base_url: str = DEFAULT_URL, **options: Any) -> None:
        super().__init__(base_url, aio=True, **options)

    list = awaiting(list_models)
    show = awaiting(show)
    create_model = awaiting(create_model)
    version = awaiting(version)
    resolve = awaiting(resolve)
    upload = awaiting(upload)
    promote = awaiting(promote)
    archive = awaiting(archive)
    download = awaiting(download)
