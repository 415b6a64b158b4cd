"""`coexist jobs ...`: training jobs on a running server, over its job API (`services.jobs_api`).

    coexist jobs submit task --goals a2 --steps 2000 [--wait]   # queue `coexist train task ...`
    coexist jobs submit zoo --env particle --combos a2+b3 --seed 1
    coexist jobs list [--limit 20]                               # newest first
    coexist jobs status 3f9c...                                  # one job in full
    coexist jobs logs 3f9c... [--follow] [--tail 4000]
    coexist jobs cancel 3f9c... [--no-wait]

Every command takes `--server` (default http://127.0.0.1:8000, like `coexist run`) and `--token`
(default: `COEXIST_ADMIN_TOKEN`, the server's admin token; submit and cancel need it, the others
only when the server wants a token for reads). `submit --wait` and `cancel` poll until the job has
ended; `--wait` exits 0 only when the job succeeded (1 when it failed, was interrupted or
cancelled; its last log lines go to stderr). Errors print one line and exit with 2 (bad input) or
1 (anything else), never a traceback; Ctrl-C while waiting leaves the job alone.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Annotated

import typer
from rich import box
from rich.console import Console
from rich.markup import escape
from rich.table import Table

if TYPE_CHECKING:
    from coexist_client.jobs import JobInfo, JobsClient

app = typer.Typer(
    help="Submit, watch and cancel training jobs on a running server.", no_args_is_help=True
)
PIPE_WIDTH = 160  # table width when the output is not a terminal (and COLUMNS is unset)
KINDS = ("task", "impact", "joint", "zoo")
STATUS_STYLE = {
    "queued": "yellow",
    "running": "cyan",
    "cancelling": "magenta",
    "succeeded": "green",
    "failed": "red",
    "gate_failed": "red",
    "interrupted": "red",
    "cancelled": "yellow",
}

ServerOpt = Annotated[str, typer.Option(help="Server URL (REST), e.g. http://127.0.0.1:8000.")]
TokenOpt = Annotated[
    str | None,
    typer.Option(
        envvar="COEXIST_ADMIN_TOKEN",
        show_default=False,
        help="Bearer token (admin token for submit/cancel).",
    ),
]
PollOpt = Annotated[float, typer.Option(min=0.05, help="Seconds between polls while waiting.")]
DEFAULT_SERVER = "http://127.0.0.1:8000"
TOKEN_HINT = " (pass --token or set COEXIST_ADMIN_TOKEN)"


def _console(*, stderr: bool = False) -> Console:
    """A console made per call, so COLUMNS is read when the command runs, not at import."""
    console = Console(stderr=stderr, soft_wrap=stderr)
    if not console.is_terminal and "COLUMNS" not in os.environ:
        console.width = PIPE_WIDTH
    return console


def _fail(message: str, code: int = 1) -> typer.Exit:
    _console(stderr=True).print(
        f"[red]error:[/red] {escape(message)}", highlight=False, markup=True
    )
    return typer.Exit(code)


@contextmanager
def _client(server: str, token: str | None) -> Iterator[JobsClient]:
    """A client of the server; SDK errors become one line and an exit code."""
    from coexist_client import CoexistError, InvalidArgument
    from coexist_client.jobs import JobsClient

    try:
        with JobsClient(server, token=token) as client:
            yield client
    except ValueError as err:  # an address that cannot be one (coexist_client.address)
        raise _fail(str(err), 2) from None
    except InvalidArgument as err:
        raise _fail(str(err), 2) from None  # names the field
    except CoexistError as err:
        hint = TOKEN_HINT if err.code in ("unauthenticated", "permission_denied") else ""
        raise _fail(f"{err.message}{hint}") from None
    except KeyboardInterrupt:
        _console(stderr=True).print("stopped waiting; the job itself goes on", highlight=False)
        raise typer.Exit(130) from None


def _styled(status: str) -> str:
    style = STATUS_STYLE.get(status)
    return f"[{style}]{status}[/{style}]" if style else status


def _when(t: datetime | None, *, seconds: bool = True) -> str:
    """Local time (the server sends UTC)."""
    form = "%Y-%m-%d %H:%M:%S" if seconds else "%Y-%m-%d %H:%M"
    return "-" if t is None else t.astimezone().strftime(form)


def _took(job: JobInfo) -> str:
    """Run time so far (running) or in all (finished); '-' before it starts."""
    if job.started_at is None:
        return "-"
    end = job.finished_at or datetime.now(UTC)
    seconds = max(0.0, (end - job.started_at).total_seconds())
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, secs = divmod(int(seconds), 60)
    if minutes < 60:
        return f"{minutes} min {secs:02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


def _what(job: JobInfo, *, short: bool = False) -> str:
    """The job's arguments the way `coexist train` is given them (`short`: for a table cell)."""
    args = job.args
    pairs = [("env", args.get("env", "particle"))]
    if job.kind != "joint":
        pairs.append(("goals", args.get("goals", "all")))
    if args.get("combos"):
        pairs.append(("combos", args["combos"]))
    pairs.append(("seed", args.get("seed", 0)))
    if args.get("steps") is not None:
        pairs.append(("steps", args["steps"]))
    return " ".join(f"{k}={v}" if short else f"--{k} {v}" for k, v in pairs)


def _exit_code(job: JobInfo) -> str:
    return "-" if job.exit_code is None else str(job.exit_code)


def _ended(job: JobInfo) -> str:
    """One line on how a finished job ended."""
    return (
        f"job {job.id}: {_styled(job.status)} after {_took(job)} "
        f"(exit code {_exit_code(job)}, {job.attempts} attempt(s))"
    )


def _print_log_tail(client: JobsClient, job_id: str, lines: int = 20) -> None:
    text = client.logs(job_id, tail=16_000).text
    last = "\n".join(text.rstrip("\n").splitlines()[-lines:])
    if last:
        typer.echo(f"--- last {lines} lines of its log:\n{last}", err=True)


@app.command()
def submit(
    kind: Annotated[str, typer.Argument(help="task, impact, joint or zoo.")],
    env: Annotated[str, typer.Option(help="Environment.")] = "particle",
    goals: Annotated[str, typer.Option(help="'all' or comma-separated goal ids.")] = "all",
    combos: Annotated[str, typer.Option(help="JL combinations, e.g. a2+b3,c+c4.")] = "",
    seed: Annotated[int, typer.Option(min=0, help="Seed of the training run.")] = 0,
    steps: Annotated[
        int | None, typer.Option(min=1, help="Env steps per batch (default: the config's).")
    ] = None,
    wait: Annotated[bool, typer.Option(help="Wait until it ends; exit 1 unless it succeeded.")] = (
        False
    ),
    poll: PollOpt = 1.0,
    server: ServerOpt = DEFAULT_SERVER,
    token: TokenOpt = None,
) -> None:
    """Queue a training job (`coexist train KIND ...` on the server)."""
    if kind not in KINDS:
        raise _fail(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}", 2)
    with _client(server, token) as client:
        job = client.submit(kind, env=env, goals=goals, combos=combos, seed=seed, steps=steps)
        _console().print(
            f"job {job.id}: {_styled(job.status)} (train {job.kind} {_what(job)})", highlight=False
        )
        if not wait:
            return

        def show(update: JobInfo) -> None:
            if update.status != job.status and not update.finished:
                _console().print(
                    f"job {update.id}: {_styled(update.status)} (attempt {update.attempts})",
                    highlight=False,
                )

        done = client.wait(job.id, poll_s=poll, on_change=show)
        _console().print(_ended(done), highlight=False)
        if not done.succeeded:
            _print_log_tail(client, done.id)
            raise typer.Exit(1)


@app.command("list")
def list_jobs(
    limit: Annotated[int, typer.Option(min=1, max=1000, help="How many (newest first).")] = 100,
    server: ServerOpt = DEFAULT_SERVER,
    token: TokenOpt = None,
) -> None:
    """The newest jobs in a table."""
    with _client(server, token) as client:
        jobs = client.list(limit)
    table = Table(title=f"{len(jobs)} job(s)", title_justify="left", box=box.SIMPLE_HEAD)
    for column in ("id", "kind", "status", "created", "took", "exit", "arguments"):
        table.add_column(column, no_wrap=column != "arguments")
    for job in jobs:
        table.add_row(
            job.id,
            job.kind,
            _styled(job.status),
            _when(job.created_at, seconds=False),
            _took(job),
            _exit_code(job),
            _what(job, short=True),
        )
    _console().print(table)


@app.command()
def status(
    job_id: Annotated[str, typer.Argument(metavar="ID", help="The job's id.")],
    server: ServerOpt = DEFAULT_SERVER,
    token: TokenOpt = None,
) -> None:
    """One job in full."""
    with _client(server, token) as client:
        job = client.get(job_id)
    table = Table(show_header=False, box=None, pad_edge=False)
    table.add_column(style="bold", no_wrap=True)
    table.add_column()
    for name, value in (
        ("id", job.id),
        ("status", _styled(job.status)),
        ("train", f"{job.kind} {_what(job)}"),
        ("attempts", str(job.attempts)),
        ("created", _when(job.created_at)),
        ("started", _when(job.started_at)),
        ("finished", _when(job.finished_at)),
        ("took", _took(job)),
        ("exit code", _exit_code(job)),
        ("run dir", job.run_dir),
    ):
        table.add_row(name, value)
    _console().print(table)


@app.command()
def logs(
    job_id: Annotated[str, typer.Argument(metavar="ID", help="The job's id.")],
    follow: Annotated[
        bool, typer.Option("--follow", "-f", help="Print the whole log and what it adds.")
    ] = False,
    tail: Annotated[int, typer.Option(min=1, help="Characters to print (not --follow).")] = (
        64_000
    ),
    poll: PollOpt = 1.0,
    server: ServerOpt = DEFAULT_SERVER,
    token: TokenOpt = None,
) -> None:
    """A job's log (stdout and stderr of its `coexist train`); --follow until the job ends."""
    with _client(server, token) as client:
        if not follow:
            typer.echo(client.logs(job_id, tail=tail).text, nl=False)
            return
        for chunk in client.follow_logs(job_id, poll_s=poll):
            typer.echo(chunk, nl=False)


@app.command()
def cancel(
    job_id: Annotated[str, typer.Argument(metavar="ID", help="The job's id.")],
    wait: Annotated[bool, typer.Option(help="Wait until a running job has stopped.")] = True,
    poll: PollOpt = 1.0,
    server: ServerOpt = DEFAULT_SERVER,
    token: TokenOpt = None,
) -> None:
    """Cancel a queued job, or stop a running one (networks it registered stay in the store)."""
    with _client(server, token) as client:
        job = client.cancel(job_id)
        if job.status == "cancelled":
            _console().print(f"job {job.id}: {_styled(job.status)} while queued", highlight=False)
            return
        _console().print(f"job {job.id}: {_styled(job.status)}", highlight=False)
        if not wait:
            return
        done = client.wait(job.id, poll_s=poll)
        _console().print(_ended(done), highlight=False)
        if done.status != "cancelled":  # it ended by itself before the runner could stop it
            raise typer.Exit(1)
