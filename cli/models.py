"""`coexist models ...`: look at and manage the model registry, straight through the store.

    coexist models list [--env particle] [--kind task] [--goal a3] [--tag team=x]
    coexist models show particle/task/a3 [--version 2]       # model, versions, aliases, lineage
    coexist models promote particle/task/a3 2 [--alias production]
    coexist models archive particle/task/a3 1
    coexist models export particle/task/a3@production --out exported/
    coexist models import exported/ --name particle/task/a3 [--alias latest --alias production]
    coexist models migrate                                    # upgrade the database schema

Every command takes `--store-url` (default: `COEXIST_STORE_URL`, else the SQLite file in
`COEXIST_DATA_DIR`), or, all but `migrate`, `--server URL` to work through a running server's
registry API instead (`cli.registry_remote`; token from `COEXIST_ADMIN_TOKEN`, else
`COEXIST_READ_TOKEN`): an operator needs no access to the database. An export directory holds `spec.json`, `lineage.json`, `model.json`,
`weights.safetensors` and `sha256` (in `sha256sum` format); `import` checks the sha256 before
registering, creates the model from `model.json` (env, kind, goals, sizes) when it does not
exist yet, and points `latest` (plus any `--alias`) at the new version.
Errors print one line and exit with 2 (bad input) or 1 (anything else), never a traceback.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

if TYPE_CHECKING:
    from model_store.entities import RegisteredModel
    from model_store.store import ModelStore

app = typer.Typer(
    help="List, inspect, promote, export and import registered models.", no_args_is_help=True
)
PIPE_WIDTH = 160  # table width when the output is not a terminal (and COLUMNS is unset)


def _console(*, stderr: bool = False) -> Console:
    """A console made per call, so COLUMNS is read when the command runs, not at import."""
    console = Console(stderr=stderr, soft_wrap=stderr)
    if not console.is_terminal and "COLUMNS" not in os.environ:
        console.width = PIPE_WIDTH
    return console


StoreUrl = Annotated[
    str | None,
    typer.Option("--store-url", help="Store URL (default: COEXIST_STORE_URL or SQLite)."),
]


Server = Annotated[
    str | None,
    typer.Option(
        "--server",
        help="A server's URL: use its registry API instead of the database "
        "(token: COEXIST_ADMIN_TOKEN, else COEXIST_READ_TOKEN).",
    ),
]


@contextmanager
def _store(
    url: str | None, server: str | None = None, *, create: bool = False
) -> Iterator[ModelStore]:
    """Open the store (or, with `server`, the server's registry behind the same methods);
    domain errors become a one-line message and an exit code. Only `create` (the commands that
    write a first model or the schema) makes a SQLite file that does not exist: a mistyped path
    is an error naming it, not an empty store."""
    from coexist_client import CoexistError
    from coexist_client import InvalidArgument as RemoteInvalid

    from cli.registry_remote import RemoteRegistry
    from model_store.defaults import open_store
    from model_store.errors import InvalidArgument, ModelStoreError

    if url is not None and server is not None:
        raise _fail("--server: give either --server or --store-url")
    try:
        if server is not None:
            remote = RemoteRegistry(server)
            try:
                yield remote  # type: ignore[misc]  # the store's methods, over HTTP
            finally:
                remote.close()
        else:
            with open_store(url, create=create) as store:
                yield store
    except (InvalidArgument, RemoteInvalid, ValueError) as exc:  # ValueError: a bad --server
        _console(stderr=True).print(f"[red]error:[/red] {escape(str(exc))}", highlight=False)
        raise typer.Exit(2) from None
    except (ModelStoreError, CoexistError) as exc:
        _console(stderr=True).print(f"[red]error:[/red] {escape(str(exc))}", highlight=False)
        raise typer.Exit(1) from None


def _fail(message: str, code: int = 2) -> typer.Exit:
    _console(stderr=True).print(f"[red]error:[/red] {escape(message)}", highlight=False)
    return typer.Exit(code)


def _when(ts: Any) -> str:
    return ts.strftime("%Y-%m-%d %H:%M")


@app.command("list")
def list_models(
    env: Annotated[str | None, typer.Option(help="Only this environment.")] = None,
    kind: Annotated[str | None, typer.Option(help="task, impact, joint or monitor.")] = None,
    goal: Annotated[str | None, typer.Option(help="Only models with this goal.")] = None,
    tag: Annotated[str | None, typer.Option(help="'key' or 'key=value'.")] = None,
    store_url: StoreUrl = None,
    server: Server = None,
) -> None:
    """List registered models (all pages) in a table."""
    with _store(store_url, server) as store:
        models: list[RegisteredModel] = []
        token: str | None = None
        while True:
            page = store.list_models(
                env=env, kind=kind, goal=goal, tag=tag, page_token=token, page_size=200
            )
            models += page.items
            if (token := page.next_page_token) is None:
                break
    table = Table(title=f"{len(models)} model(s)", title_justify="left")
    for column in ("name", "kind", "goals", "obs", "actions", "aliases", "tags", "updated"):
        table.add_column(column, no_wrap=column in ("name", "updated"))
    for m in models:
        aliases = ", ".join(f"{a}→{v}" for a, v in m.aliases.items())
        tags = ", ".join(f"{k}={v}" for k, v in m.tags.items())
        table.add_row(
            m.name,
            m.kind,
            "+".join(m.goals),
            str(m.obs_dim),
            str(m.n_actions),
            aliases or "-",
            tags or "-",
            _when(m.updated_at),
        )
    _console().print(table)


@app.command()
def show(
    name: Annotated[str, typer.Argument(help="Model name, e.g. particle/task/a3.")],
    version: Annotated[int | None, typer.Option(help="Print this version's full lineage.")] = None,
    store_url: StoreUrl = None,
    server: Server = None,
) -> None:
    """A model, its versions and aliases, and lineage."""
    with _store(store_url, server) as store:
        model = store.get_model(name)
        versions = store.list_versions(name)
        detail = store.get_version(name, version) if version is not None else None
    _console().print(
        f"[bold]{model.name}[/bold]  ({model.kind}, env {model.env}, goals "
        f"{'+'.join(model.goals)}, obs {model.obs_dim}, actions {model.n_actions})"
    )
    if model.description:
        _console().print(model.description)
    _console().print(f"tags: {json.dumps(model.tags)}   aliases: {json.dumps(model.aliases)}")
    by_version: dict[int, list[str]] = {}
    for alias, number in model.aliases.items():
        by_version.setdefault(number, []).append(alias)
    table = Table(title="versions", title_justify="left")
    for column in ("version", "status", "aliases", "sha256", "size", "created", "lineage"):
        table.add_column(column, no_wrap=column != "lineage")
    for v in versions:
        lineage = v.lineage
        summary = f"seed {lineage.seed}, code {lineage.code_version}, by {lineage.registered_by}"
        if lineage.parents:
            summary += f", parents {', '.join(lineage.parents)}"
        table.add_row(
            str(v.version),
            v.status,
            ", ".join(by_version.get(v.version, [])) or "-",
            v.sha256[:12],
            f"{v.size_bytes:,} B",
            _when(v.created_at),
            summary,
        )
    _console().print(table)
    if detail is not None:
        _console().print_json(
            json.dumps({"spec": detail.spec, "lineage": detail.lineage.to_json()})
        )


@app.command()
def promote(
    name: Annotated[str, typer.Argument(help="Model name.")],
    version: Annotated[int, typer.Argument(help="Version to point the alias at.")],
    alias: Annotated[str, typer.Option(help="Alias to set or move.")] = "production",
    store_url: StoreUrl = None,
    server: Server = None,
) -> None:
    """Point an alias (default: production) at a version, atomically."""
    with _store(store_url, server) as store:
        before = store.get_model(name).aliases.get(alias)
        if server is None:  # a server checks it itself (`services.engine.admission`)
            from services.engine.admission import refuse_unservable_version

            refuse_unservable_version(store, name, version, alias)
        store.set_alias(name, alias, version)
    moved = f"from {before} " if before is not None else ""
    _console().print(f"{name}@{alias}: moved {moved}to version {version}")


@app.command()
def archive(
    name: Annotated[str, typer.Argument(help="Model name.")],
    version: Annotated[int, typer.Argument(help="Version to archive (its data is kept).")],
    store_url: StoreUrl = None,
    server: Server = None,
) -> None:
    """Archive a version (refused while an alias points at it)."""
    with _store(store_url, server) as store:
        store.archive_version(name, version)
    _console().print(f"{name}/{version}: archived")


@app.command()
def export(
    ref: Annotated[str, typer.Argument(help="name@alias, name/version or name (= @production).")],
    out_dir: Annotated[Path, typer.Option("--out", help="Directory to write into.")],
    store_url: StoreUrl = None,
    server: Server = None,
) -> None:
    """Write a version's spec, lineage, model metadata, weights and sha256 to a directory."""
    with _store(store_url, server) as store:
        mv = store.resolve(ref)
        model = store.get_model(mv.name)
        weights = store.load_weights(mv.name, mv.version)  # sha256 verified
    out_dir.mkdir(parents=True, exist_ok=True)
    meta = {
        k: v
        for k, v in model.to_json().items()
        if k in ("name", "env", "kind", "goals", "obs_dim", "n_actions", "description", "tags")
    }
    (out_dir / "spec.json").write_text(json.dumps(mv.spec, indent=2) + "\n")
    (out_dir / "lineage.json").write_text(json.dumps(mv.lineage.to_json(), indent=2) + "\n")
    (out_dir / "model.json").write_text(json.dumps({**meta, "version": mv.version}, indent=2))
    (out_dir / "weights.safetensors").write_bytes(weights)
    (out_dir / "sha256").write_text(f"{mv.sha256}  weights.safetensors\n")
    _console().print(
        f"exported {mv.ref} ({mv.size_bytes:,} B, sha256 {mv.sha256[:12]}) to {out_dir}"
    )


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise _fail(f"{path}: missing") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise _fail(f"{path}: not readable JSON ({exc})") from None


@app.command("import")
def import_(
    src: Annotated[Path, typer.Argument(help="Directory written by `coexist models export`.")],
    name: Annotated[str | None, typer.Option(help="Model name (default: model.json's).")] = None,
    alias: Annotated[
        list[str] | None, typer.Option(help="Aliases to set (default: latest).")
    ] = None,
    store_url: StoreUrl = None,
    server: Server = None,
) -> None:
    """Register an exported version (checksum checked) under NAME, creating the model if needed."""
    from coexist_client import NotFound as RemoteNotFound

    from model_store.artifacts import sha256_hex
    from model_store.entities import Lineage
    from model_store.errors import NotFound

    spec, lineage_json = _read_json(src / "spec.json"), _read_json(src / "lineage.json")
    meta = _read_json(src / "model.json") if (src / "model.json").exists() else {}
    try:
        weights = (src / "weights.safetensors").read_bytes()
    except OSError as exc:
        raise _fail(f"{src / 'weights.safetensors'}: {exc.strerror or exc}") from None
    if (src / "sha256").exists():
        expected = (src / "sha256").read_text().split()[0]
        if sha256_hex(weights) != expected:
            raise _fail(f"{src / 'weights.safetensors'}: sha256 does not match {src / 'sha256'}", 1)
    target = name or meta.get("name")
    if not target:
        raise _fail("--name: required (the directory has no model.json)")
    with _store(store_url, server, create=True) as store:  # importing into a new store
        try:
            store.get_model(target)
        except (NotFound, RemoteNotFound):
            if not meta:
                raise _fail(
                    f"model {target!r} does not exist and {src} has no model.json"
                ) from None
            store.create_model(
                target,
                env=meta["env"],
                kind=meta["kind"],
                goals=meta["goals"],
                obs_dim=meta["obs_dim"],
                n_actions=meta["n_actions"],
                description=meta.get("description", ""),
                tags=meta.get("tags"),
            )
        if server is None:  # a server checks it itself (`services.engine.admission`)
            from services.engine.admission import refuse_unservable_upload

            refuse_unservable_upload(spec, weights)
        mv = store.register_version(
            target,
            spec=spec,
            weights=weights,
            lineage=Lineage.from_json(lineage_json),
            aliases=("latest", *(alias or [])),
        )
    _console().print(f"imported {src} as {mv.ref} (sha256 {mv.sha256[:12]})")


@app.command()
def migrate(store_url: StoreUrl = None) -> None:
    """Create or upgrade the store's database schema to this version of coexist."""
    with _store(store_url, create=True) as store:
        # a backend without a schema (a plugin's) has nothing to migrate: opening it is all
        revision = getattr(store, "schema_revision", "(no schema revision: nothing to migrate)")
        _console().print(f"{store!r}: schema at {revision}")
