"""Entry point of the `coexist` command.

Each job lives in its own module and registers itself here; heavy imports (torch, the server)
happen inside the command functions so that `coexist --help` answers at once.
"""

from __future__ import annotations

import typer

from cli import demo

app = typer.Typer(
    name="coexist",
    help="coexist: a policy server for multi-agent coexistence (AAIL).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

app.command("demo")(demo.demo)


if __name__ == "__main__":  # pragma: no cover
    app()
