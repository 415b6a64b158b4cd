"""`coexist env`: the registered environments, and the conformance check of one.

coexist env list               # every environment this installation knows, and where from
coexist env check NAME         # `envs.check`: one line per check; exit 1 if any fails
"""

from __future__ import annotations

from typing import Annotated

import typer

app = typer.Typer(help="Environments: list them, check one.", no_args_is_help=True)


@app.command("list")
def list_envs() -> None:
    """Every registered environment (`coexist.envs` entry points) with its goals and agents."""
    from rich.console import Console
    from rich.table import Table

    from envs.registry import get_domain, known_envs

    table = Table("env", "goals", "agents", "actions")
    for name in known_envs():
        d = get_domain(name)
        goals = ", ".join(d.goals[:6]) + (", ..." if len(d.goals) > 6 else "")
        table.add_row(name, f"{len(d.goals)}: {goals}", f"1..{d.max_agents}", str(d.n_actions))
    Console().print(table)


@app.command("check")
def check(
    name: Annotated[str, typer.Argument(help="The environment's registered name.")],
    episodes: Annotated[int, typer.Option(min=1, help="Seeded episodes to play.")] = 3,
    seed: Annotated[int, typer.Option(min=0, help="Seed of the episodes and goal draws.")] = 0,
) -> None:
    """Check an environment's registration (envs/check.py): PettingZoo's API test, the views'
    shapes, the perspective transform, the goals, seeded episodes, the drawing's JSON."""
    from rich.console import Console
    from rich.markup import escape

    from envs.check import check_env

    console = Console()
    try:
        results = check_env(name, episodes=episodes, seed=seed)
    except ValueError as err:
        raise typer.BadParameter(str(err), param_hint="NAME") from None
    for result in results:
        mark = "[green]ok[/green]  " if result.passed else "[red]FAIL[/red]"
        console.print(f"{mark} {result.name}: {escape(result.message)}")
    failed = [r for r in results if not r.passed]
    if failed:
        console.print(f"[red]{len(failed)} of {len(results)} checks failed[/red]")
        raise typer.Exit(1)
    console.print(f"[green]{name}: all {len(results)} checks passed[/green]")
