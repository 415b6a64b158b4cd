"""Entry point of the `coexist` command.

Each job lives in its own module and registers itself here; heavy imports (torch, the server)
happen inside the command functions so that `coexist --help` answers at once.
"""

from __future__ import annotations

from typing import Annotated

import typer

from cli import demo, env, evaluate, jobs, models, run, serve, train

app = typer.Typer(
    name="coexist",
    help="coexist: a policy server for multi-agent coexistence (AAIL).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _print_version(asked: bool) -> None:
    if asked:
        from services.version import VERSION  # the VERSION file, as installed

        typer.echo(f"coexist {VERSION}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_print_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """coexist: train, store and serve AAIL task and impact networks."""


app.command("demo")(demo.demo)
app.command("run")(run.run)
app.command("eval")(evaluate.evaluate)
app.command("serve")(serve.serve)
app.add_typer(train.app, name="train")
app.add_typer(models.app, name="models")
app.add_typer(jobs.app, name="jobs")
app.add_typer(env.app, name="env")


if __name__ == "__main__":  # pragma: no cover
    app()
