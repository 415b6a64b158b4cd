"""A model store backend for coexist's plugin tests that keeps no SQL database, picked by the URL
scheme `tinyline`: `tinyline:///DIR` keeps its models in the folder DIR, everything but the
weights in one JSON file (`state.json`, replaced whole on every write) and each version's weights
in a file named by their sha256 (`weights/`). Every read and write holds a `flock` of `DIR/lock`
(shared to read, exclusive to write), so the processes that open one folder (the CLI, the server,
a training job's subprocess, Ray workers) see one store, each call one transaction.

Every process that opens the store appends a line to `DIR/opened` (its process id and command),
so a test can see which processes picked this backend by its scheme. `lock(key)` gives coexist's
Ray backend the lock it holds while a batch publishes (`ModelStore.lock`).

Small on purpose: the whole state is read and written on each call, fine for a test's zoo."""

from __future__ import annotations

import base64
import binascii
import fcntl
import hashlib
import hmac
import json
import os
import sys
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from model_store.artifacts import check_artifact, sha256_hex
from model_store.checks import check_kind, check_new_model, check_registration
from model_store.entities import Event, Lineage, ModelVersion, Page, RegisteredModel
from model_store.errors import (
    AlreadyExists,
    ChecksumMismatch,
    Conflict,
    InvalidArgument,
    InvalidArtifact,
    NotFound,
    brief,
)
from model_store.naming import (
    MAX_VERSION,
    parse_ref,
    path_prefixes,
    ref_candidates,
    validate_alias,
    validate_tags,
    validate_text,
)
from model_store.store import ModelStore

SCHEME = "tinyline://"
MAX_PAGE = 1000
MAX_EVENT_ID = 2**63 - 1
State = dict[str, Any]


def _now() -> str:
    return datetime.now(UTC).isoformat()


def _time(text: str) -> datetime:
    return datetime.fromisoformat(text)


def _number(value: object, field: str, limit: int) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= limit:
        raise InvalidArgument(
            f"{field}: expected an integer in 1..{limit}, got {brief(value)}", field=field
        )
    return value


class TinylineStore(ModelStore):
    def __init__(self, url: str, *, create: bool = True, max_artifact_bytes: int = 64 << 20):
        if not url.startswith(SCHEME) or not url.removeprefix(SCHEME):
            raise InvalidArgument(
                f"store_url: expected {SCHEME}/DIR, got {url!r}", field="store_url"
            )
        self.path = Path(url.removeprefix(SCHEME)).expanduser().absolute()
        self.max_artifact_bytes = max_artifact_bytes
        if not (self.path / "state.json").is_file():
            if not create:  # a reader must not make an empty store where the URL names none
                raise InvalidArgument(
                    f"store_url: no tinyline store in {str(self.path)!r}", field="store_url"
                )
            (self.path / "weights").mkdir(parents=True, exist_ok=True)
            with self._locked(exclusive=True):
                if not (self.path / "state.json").is_file():
                    self._save({"store_id": uuid.uuid4().hex, "seq": 0, "models": {}, "events": []})
        with open(self.path / "opened", "a") as log:
            log.write(f"{os.getpid()} {' '.join(sys.argv[1:4])}\n")

    def reopen_url(self) -> str:
        return f"{SCHEME}{self.path}"

    def __repr__(self) -> str:
        return f"TinylineStore({self.reopen_url()!r})"

    # --- the one-file transactions ------------------------------------------------------
    @contextmanager
    def _locked(self, *, exclusive: bool, name: str = "lock") -> Iterator[None]:
        with open(self.path / name, "a+b") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
            yield  # closing the file releases the lock, also when the process dies

    def _load(self) -> State:
        state: State = json.loads((self.path / "state.json").read_text())
        return state

    def _save(self, state: State) -> None:
        temporary = self.path / "state.json.new"
        temporary.write_text(json.dumps(state))
        os.replace(temporary, self.path / "state.json")  # readers see the old or the new whole

    @contextmanager
    def _read(self) -> Iterator[State]:
        with self._locked(exclusive=False):
            yield self._load()

    @contextmanager
    def _write(self) -> Iterator[State]:
        """The state to change; saved when the block ends without an error, else dropped."""
        with self._locked(exclusive=True):
            state = self._load()
            yield state
            self._save(state)

    @staticmethod
    def _emit(
        state: State, kind: str, name: str, version: int | None = None, alias: str | None = None
    ) -> None:
        state["seq"] += 1
        event = {"id": state["seq"], "kind": kind, "name": name, "version": version}
        state["events"].append({**event, "alias": alias, "at": _now()})

    @staticmethod
    def _model(state: State, name: str) -> dict[str, Any]:
        model: dict[str, Any] | None = state["models"].get(name)
        if model is None:
            raise NotFound(f"model {name!r} not found", field="name")
        return model

    @staticmethod
    def _version(model: dict[str, Any], name: str, version: int) -> dict[str, Any]:
        row: dict[str, Any] | None = model["versions"].get(str(version))
        if row is None:
            raise NotFound(f"model {name!r} has no version {version}", field="version")
        return row

    @staticmethod
    def _entity(name: str, model: dict[str, Any]) -> RegisteredModel:
        return RegisteredModel(
            name=name,
            env=model["env"],
            kind=model["kind"],
            goals=tuple(model["goals"]),
            obs_dim=model["obs_dim"],
            n_actions=model["n_actions"],
            description=model["description"],
            tags=dict(sorted(model["tags"].items())),
            aliases=dict(sorted(model["aliases"].items())),
            created_at=_time(model["created_at"]),
            updated_at=_time(model["updated_at"]),
        )

    @staticmethod
    def _version_entity(name: str, version: int, row: dict[str, Any]) -> ModelVersion:
        return ModelVersion(
            name=name,
            version=version,
            spec=dict(row["spec"]),
            sha256=row["sha256"],
            size_bytes=row["size_bytes"],
            created_at=_time(row["created_at"]),
            status=row["status"],
            lineage=Lineage.from_json(row["lineage"]),
        )

    def _drop_unused_weights(self, state: State, sha256s: set[str]) -> None:
        used = {
            row["sha256"]
            for model in state["models"].values()
            for row in model["versions"].values()
        }
        for sha256 in sha256s - used:
            (self.path / "weights" / sha256).unlink(missing_ok=True)

    # --- registered models --------------------------------------------------------------
    def create_model(
        self,
        name: str,
        *,
        env: str,
        kind: str,
        goals: Sequence[str],
        obs_dim: int,
        n_actions: int,
        description: str = "",
        tags: Mapping[str, str] | None = None,
        exist_ok: bool = False,
    ) -> RegisteredModel:
        goal_list, tag_map = check_new_model(
            name,
            env=env,
            kind=kind,
            goals=goals,
            obs_dim=obs_dim,
            n_actions=n_actions,
            description=description,
            tags=tags,
        )
        with self._write() as state:
            models = state["models"]
            if name in models:
                made = models[name]
                same = (
                    made["env"],
                    made["kind"],
                    made["goals"],
                    made["obs_dim"],
                    made["n_actions"],
                )
                if exist_ok and same == (env, kind, goal_list, obs_dim, n_actions):
                    return self._entity(name, made)
                raise AlreadyExists(f"model {name!r} already exists", field="name")
            nested = [n for n in models if n in path_prefixes(name) or n.startswith(name + "/")]
            if nested:  # `name/3` must name one thing (`model_store.naming`)
                raise Conflict(
                    f"name: {name!r} and the existing model {nested[0]!r} would make refs "
                    "ambiguous (one name is a path prefix of the other)",
                    field="name",
                )
            stamp = _now()
            models[name] = {
                "env": env,
                "kind": kind,
                "goals": goal_list,
                "obs_dim": obs_dim,
                "n_actions": n_actions,
                "description": description,
                "tags": tag_map,
                "aliases": {},
                "created_at": stamp,
                "updated_at": stamp,
                "last_version": 0,
                "versions": {},
            }
            self._emit(state, "model_created", name)
            return self._entity(name, models[name])

    def get_model(self, name: str) -> RegisteredModel:
        with self._read() as state:
            return self._entity(name, self._model(state, name))

    def list_models(
        self,
        *,
        env: str | None = None,
        kind: str | None = None,
        goal: str | None = None,
        tag: str | None = None,
        page_size: int = 50,
        page_token: str | None = None,
    ) -> Page[RegisteredModel]:
        if not isinstance(page_size, int) or not 1 <= page_size <= MAX_PAGE:
            raise InvalidArgument(
                f"page_size: expected 1..{MAX_PAGE}, got {brief(page_size)}", field="page_size"
            )
        for field, value in (("env", env), ("goal", goal), ("tag", tag)):
            if value is not None:
                validate_text(value, field)
        if kind is not None:
            check_kind(kind)
        after = _after(page_token) if page_token else None
        key, has_value, value = (tag or "").partition("=")

        def wanted(name: str, model: dict[str, Any]) -> bool:
            tags = model["tags"]
            return (
                (after is None or name > after)
                and env in (None, model["env"])
                and kind in (None, model["kind"])
                and (goal is None or goal in model["goals"])
                and (tag is None or (key in tags and (not has_value or tags[key] == value)))
            )

        with self._read() as state:
            found = [(n, m) for n, m in sorted(state["models"].items()) if wanted(n, m)]
        items = tuple(self._entity(n, m) for n, m in found[:page_size])
        more = len(found) > page_size
        return Page(items=items, next_page_token=_token(items[-1].name) if more else None)

    def update_model(
        self, name: str, *, description: str | None = None, tags: Mapping[str, str] | None = None
    ) -> RegisteredModel:
        if description is not None:
            validate_text(description, "description")
        tag_map = validate_tags(tags) if tags is not None else None
        with self._write() as state:
            model = self._model(state, name)
            if description is not None:
                model["description"] = description
            if tag_map is not None:
                model["tags"] = tag_map
            model["updated_at"] = _now()
            self._emit(state, "model_updated", name)
            return self._entity(name, model)

    def delete_model(self, name: str) -> None:
        with self._write() as state:
            model = self._model(state, name)
            del state["models"][name]
            self._emit(state, "model_deleted", name)
            self._drop_unused_weights(state, {r["sha256"] for r in model["versions"].values()})

    # --- versions -----------------------------------------------------------------------
    def register_version(
        self,
        name: str,
        *,
        spec: dict,
        weights: bytes,
        lineage: Lineage,
        aliases: Sequence[str] = ("latest",),
        idempotency_key: str | None = None,
    ) -> ModelVersion:
        alias_list = check_registration(aliases, idempotency_key, lineage)
        registered = self.get_model(name)
        sizes = (registered.obs_dim, registered.n_actions)
        artifact = check_artifact(
            spec, weights, obs_dim=sizes[0], n_actions=sizes[1], max_bytes=self.max_artifact_bytes
        )
        with self._write() as state:
            model = self._model(state, name)
            if (model["obs_dim"], model["n_actions"]) != sizes:
                raise InvalidArtifact(f"model {name!r} changed during upload; retry", field="name")
            for number, row in model["versions"].items():
                if idempotency_key is not None and row["idempotency_key"] == idempotency_key:
                    if row["sha256"] != artifact.sha256 or row["spec"] != artifact.spec:
                        raise Conflict(
                            f"idempotency_key: {idempotency_key!r} registered version {number} "
                            "from other weights or another spec: a key names one upload",
                            field="idempotency_key",
                        )
                    return self._version_entity(name, int(number), row)
            for i, parent in enumerate(lineage.parents):
                ref = parse_ref(parent)
                owner = state["models"].get(ref.name)
                if owner is None or str(ref.version) not in owner["versions"]:
                    field = f"lineage.parents[{i}]"
                    raise InvalidArtifact(f"{field}: no such version {brief(parent)}", field=field)
            (self.path / "weights" / artifact.sha256).write_bytes(bytes(weights))
            model["last_version"] += 1
            version = model["last_version"]
            model["versions"][str(version)] = {
                "spec": artifact.spec,
                "sha256": artifact.sha256,
                "size_bytes": artifact.size_bytes,
                "status": "ready",
                "lineage": lineage.to_json(),
                "created_at": _now(),
                "idempotency_key": idempotency_key,
            }
            self._emit(state, "version_registered", name, version)
            for alias in alias_list:
                self._point(state, name, model, alias, version)
            model["updated_at"] = _now()
            return self._version_entity(name, version, model["versions"][str(version)])

    def get_version(self, name: str, version: int) -> ModelVersion:
        _number(version, "version", MAX_VERSION)
        with self._read() as state:
            row = self._version(self._model(state, name), name, version)
            return self._version_entity(name, version, row)

    def list_versions(self, name: str, *, include_archived: bool = True) -> list[ModelVersion]:
        with self._read() as state:
            rows = self._model(state, name)["versions"]
        found = [
            self._version_entity(name, int(n), row)
            for n, row in rows.items()
            if include_archived or row["status"] == "ready"
        ]
        return sorted(found, key=lambda v: -v.version)

    def resolve(self, ref: str) -> ModelVersion:
        candidates = ref_candidates(ref)
        with self._read() as state:
            models = state["models"]
            parsed = next((c for c in candidates[:-1] if c.name in models), candidates[-1])
            model = self._model(state, parsed.name)
            if parsed.version is not None:
                number = parsed.version
            elif parsed.alias in model["aliases"]:
                number = model["aliases"][parsed.alias]
            else:
                known = ", ".join(sorted(model["aliases"])) or "none"
                raise NotFound(
                    f"model {parsed.name!r} has no alias {parsed.alias!r} (aliases: {known})",
                    field="alias",
                )
            row = self._version(model, parsed.name, number)
            return self._version_entity(parsed.name, number, row)

    def load_weights(self, name: str, version: int) -> bytes:
        _number(version, "version", MAX_VERSION)
        with self._read() as state:
            expected = self._version(self._model(state, name), name, version)["sha256"]
            data = (self.path / "weights" / expected).read_bytes()
        actual = sha256_hex(data)
        if not hmac.compare_digest(actual, expected):
            raise ChecksumMismatch(
                f"{name}/{version}: stored weights hash to sha256 {actual}, registered as "
                f"{expected}; the folder was changed outside coexist"
            )
        return data

    def archive_version(self, name: str, version: int) -> ModelVersion:
        _number(version, "version", MAX_VERSION)
        with self._write() as state:
            model = self._model(state, name)
            row = self._version(model, name, version)
            if row["status"] != "archived":
                self._refuse_aliased(model, name, version, "archiving")
                row["status"] = "archived"
                model["updated_at"] = _now()
                self._emit(state, "version_archived", name, version)
            return self._version_entity(name, version, row)

    def delete_version(self, name: str, version: int) -> None:
        _number(version, "version", MAX_VERSION)
        with self._write() as state:
            model = self._model(state, name)
            row = self._version(model, name, version)
            self._refuse_aliased(model, name, version, "deleting")
            del model["versions"][str(version)]
            model["updated_at"] = _now()
            self._emit(state, "version_deleted", name, version)
            self._drop_unused_weights(state, {row["sha256"]})

    @staticmethod
    def _refuse_aliased(model: dict[str, Any], name: str, version: int, doing: str) -> None:
        pointing = sorted(a for a, v in model["aliases"].items() if v == version)
        if pointing:  # dropping what an alias serves would silently stop serving it
            raise Conflict(
                f"{name}/{version} is the target of alias(es) {', '.join(pointing)}: "
                f"move or delete them before {doing}",
                field="version",
            )

    # --- aliases ------------------------------------------------------------------------
    def _point(
        self, state: State, name: str, model: dict[str, Any], alias: str, version: int
    ) -> None:
        if model["aliases"].get(alias) != version:
            model["aliases"][alias] = version
            self._emit(state, "alias_set", name, version, alias)
            model["updated_at"] = _now()

    def set_alias(self, name: str, alias: str, version: int) -> None:
        validate_alias(alias)
        _number(version, "version", MAX_VERSION)
        with self._write() as state:
            model = self._model(state, name)
            if self._version(model, name, version)["status"] != "ready":
                raise Conflict(
                    f"{name}/{version} is archived: an alias must point at a ready version",
                    field="version",
                )
            self._point(state, name, model, alias, version)

    def delete_alias(self, name: str, alias: str) -> None:
        validate_alias(alias)
        with self._write() as state:
            model = self._model(state, name)
            if alias not in model["aliases"]:
                raise NotFound(f"model {name!r} has no alias {alias!r}", field="alias")
            version = model["aliases"].pop(alias)
            model["updated_at"] = _now()
            self._emit(state, "alias_deleted", name, version, alias)

    # --- change feed and the Ray backend's lock ------------------------------------------
    def change_token(self) -> str:
        with self._read() as state:
            return f"{state['seq']}-{state['store_id'][:12]}"

    def events(self, since_id: int = 0, limit: int = 100) -> list[Event]:
        if not isinstance(since_id, int) or isinstance(since_id, bool):
            since_id = -1  # refused below, as any number out of range
        if not 0 <= since_id <= MAX_EVENT_ID:
            raise InvalidArgument(
                f"since_id: expected an integer in 0..{MAX_EVENT_ID}", field="since_id"
            )
        _number(limit, "limit", MAX_PAGE)
        with self._read() as state:
            rows = [e for e in state["events"] if e["id"] > since_id][:limit]
        return [Event(**{**e, "at": _time(e["at"])}) for e in rows]

    @contextmanager
    def lock(self, key: str) -> Iterator[None]:
        """`ModelStore.lock`: an exclusive `flock` of a file of this folder named by `key`."""
        (self.path / "locks").mkdir(exist_ok=True)
        name = f"locks/{hashlib.sha256(key.encode()).hexdigest()[:32]}"
        with self._locked(exclusive=True, name=name):
            yield


_TOKEN_PREFIX = "after:"  # so that a string that merely decodes is not taken for a token


def _token(last_name: str) -> str:
    return base64.urlsafe_b64encode(f"{_TOKEN_PREFIX}{last_name}".encode()).decode()


def _after(token: str) -> str:
    """The name a page token continues after; `InvalidArgument` for anything else."""
    try:
        text = base64.urlsafe_b64decode(token.encode()).decode()
    except (binascii.Error, ValueError):
        text = ""
    if not text.startswith(_TOKEN_PREFIX):
        raise InvalidArgument(
            "page_token: not a token returned by a previous list call", field="page_token"
        )
    return text.removeprefix(_TOKEN_PREFIX)


def open_tinyline_store(
    url: str, *, max_artifact_bytes: int = 64 << 20, auto_migrate: bool = True, create: bool = False
) -> TinylineStore:
    """The `coexist.stores` factory of the scheme `tinyline` (`auto_migrate` is moot: a folder
    of JSON has no schema to migrate)."""
    return TinylineStore(url, create=create, max_artifact_bytes=max_artifact_bytes)
