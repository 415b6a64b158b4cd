"""`coexist serve`: the inference server (REST + gRPC) over the model store.

On a first run against an empty store it first trains the particle zoo (35 task + 35 impact
networks, with progress bars; about ten minutes on 2 cores) and registers it, so the README's
first command ends with a server that answers. `--no-bootstrap` skips that. With
`COEXIST_TLS_CERT_FILE` and `COEXIST_TLS_KEY_FILE` set, REST serves HTTPS and gRPC TLS
(docs/security.md).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer


def serve(
    host: Annotated[str, typer.Option(envvar="COEXIST_HOST", help="Address to listen on.")] = (
        "127.0.0.1"
    ),
    http_port: Annotated[int, typer.Option(envvar="COEXIST_HTTP_PORT", help="REST port.")] = 8000,
    grpc_port: Annotated[
        int, typer.Option(envvar="COEXIST_GRPC_PORT", help="gRPC port (0 disables gRPC).")
    ] = 50051,
    workers: Annotated[int, typer.Option(min=1, help="uvicorn worker processes.")] = 1,
    store_url: Annotated[
        str | None,
        typer.Option(
            envvar="COEXIST_STORE_URL",
            help="Model store URL (default: SQLite in the data dir). A URL with a password "
            "belongs in COEXIST_STORE_URL: every user of the machine sees a command line.",
        ),
    ] = None,
    create_store: Annotated[
        bool,
        typer.Option(
            envvar="COEXIST_CREATE_STORE",
            help="Create a --store-url SQLite file that does not exist (the default file in "
            "the data dir is always created); without it such a path is an error.",
        ),
    ] = False,
    bootstrap: Annotated[
        bool, typer.Option(help="Train the particle zoo first if the store has none.")
    ] = True,
    bootstrap_steps: Annotated[
        int | None, typer.Option(help="Training steps per batch for the bootstrap zoo.")
    ] = None,
) -> None:
    """Serve blended action distributions over REST and gRPC."""
    # One BLAS thread per process: at batch 1 threads only add latency, and under load
    # oversubscribed BLAS threads made a batch of 256 fourteen times slower (PERF-NOTES).
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    os.environ["COEXIST_HOST"] = host
    os.environ["COEXIST_HTTP_PORT"] = str(http_port)
    os.environ["COEXIST_GRPC_PORT"] = str(grpc_port)
    os.environ["COEXIST_GRPC_ENABLED"] = "true" if grpc_port else "false"
    # with > 1 the app refuses REST sessions unless COEXIST_SESSION_STORE_URL shares them
    os.environ["COEXIST_WORKERS"] = str(workers)
    if store_url:
        os.environ["COEXIST_STORE_URL"] = store_url
    os.environ["COEXIST_CREATE_STORE"] = "true" if create_store else "false"

    from model_store.defaults import check_store_url
    from model_store.errors import InvalidArgument
    from services.http_protocol import GuardedHttpProtocol
    from services.http_server import serve as serve_http
    from services.logging import log_config
    from services.settings import InsecureSettings, Settings

    settings = Settings()
    try:
        settings.check_secure()
    except InsecureSettings as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(2) from None
    try:  # a mistyped path, a missing driver or an unknown scheme, named before anything starts
        check_store_url(settings.resolved_store_url(), create=settings.creates_store)
    except InvalidArgument as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(2) from None
    if settings.session_store_url:  # a mistyped scheme or a missing client, named now
        from services.sessions.backends import open_backend

        try:
            open_backend(settings.session_store_url, "check").close()  # connects nowhere yet
        except ValueError as err:
            typer.echo(f"error: {err}", err=True)
            raise typer.Exit(2) from None
    if bootstrap:
        _bootstrap(settings.resolved_store_url(), settings.data_dir, bootstrap_steps)
    if workers > 1:  # one /metrics for all workers: prometheus_client's multiprocess mode
        from services.metrics import prepare_multiprocess_dir

        prepare_multiprocess_dir(settings.data_dir / "prometheus")
    scheme, grpc_kind = ("https", "gRPC with TLS") if settings.tls else ("http", "gRPC")
    typer.echo(
        f"serving REST on {scheme}://{host}:{http_port} (docs at /docs)"
        + (f" and {grpc_kind} on {host}:{grpc_port}" if grpc_port else "")
    )
    serve_http(  # uvicorn, whose shutdown first answers the requests already sent
        "services.allowed_hosts:served_app",  # create_app() behind the Host check
        host=host,
        port=http_port,
        workers=workers,
        loop="uvloop",
        http=GuardedHttpProtocol,  # httptools with header, time and connection limits
        timeout_keep_alive=settings.http_keep_alive_s,
        log_config=log_config(settings.log_format, settings.log_level),
        log_level=settings.log_level,
        access_log=False,  # services.logging writes access lines, with request ids
        timeout_graceful_shutdown=settings.shutdown_grace_s,  # in-flight requests finish
        ssl_certfile=settings.tls_cert_file,  # HTTPS when COEXIST_TLS_* are set
        ssl_keyfile=settings.tls_key_file,
        # X-Forwarded-For names the client only when a configured proxy sent it: uvicorn's
        # default believes any process on 127.0.0.1, so one local client could pose as many
        # and step past its per-client bounds (docs/security.md)
        proxy_headers=bool(settings.forwarded_allow_ips.strip()),
        forwarded_allow_ips=settings.forwarded_allow_ips.strip() or None,
    )


def _bootstrap(store_url: str, data_dir: Path, steps: int | None) -> None:
    """Train and register whatever part of the particle zoo the store lacks."""
    from dataclasses import replace

    from rich.console import Console

    from cli.train import progress_bars
    from envs.particle.goals import GOAL_IDS
    from model_store.defaults import open_store
    from model_store.sql.engine import redact_url
    from trainer.config import ImpactConfig, TaskConfig
    from trainer.report import print_summary
    from trainer.zoo import RunState, goals_without, run_impacts, run_tasks

    console = Console()
    with open_store(store_url, create=True) as store:  # serve checked the path first
        tasks = goals_without(store, "particle", "task", GOAL_IDS, "latest")
        impacts = goals_without(store, "particle", "impact", GOAL_IDS, "latest")
        if not tasks and not impacts:
            return
        console.print(
            f"[bold]first run:[/bold] training the particle zoo ({len(tasks)} task and "
            f"{len(impacts)} impact networks) into {redact_url(store_url)}"
        )
        task_cfg, impact_cfg = TaskConfig(), ImpactConfig()
        if steps is not None:
            task_cfg = replace(task_cfg, total_steps=steps)
            impact_cfg = replace(impact_cfg, total_steps=steps)
        run = RunState.open(data_dir / "runs" / "bootstrap", "bootstrap", resume=True)
        # Two batches of goals, each in its own process on its own core (`trainer.parallel`):
        # the networks depend on the batches (18 + 17 goals), never on the number of workers.
        workers = max(1, min(2, os.cpu_count() or 1))
        with progress_bars() as progress:
            common = {"seed": 0, "run": run, "progress": progress}
            common.update(goals_per_batch=18, workers=workers)
            batches = run_tasks(store, tasks, task_cfg, **common) if tasks else []
            if impacts:
                batches += run_impacts(store, impacts, impact_cfg, **common)
        print_summary(batches, console)
        for kind in ("task", "impact"):
            unserved = goals_without(store, "particle", kind, GOAL_IDS, "production")
            if unserved:  # every attempt failed: say so, and how to fill the gap
                console.print(
                    f"[bold yellow]warning:[/bold yellow] no {kind} network passed its gates "
                    f"for {', '.join(unserved)}; requests that need one are refused. Train "
                    f"another: coexist train {kind} --goals {','.join(unserved)} --seed 1 "
                    f"--store-url {redact_url(store_url)}"
                )
