"""`coexist run`: episodes of any registered env against a running policy server (the
environment client).

    coexist run --server http://127.0.0.1:8000 --ego a2 --partners b3 --episodes 20
    coexist run --server grpc://127.0.0.1:50051 --ego a2 --partners a0,b2,c4,e1 --gif run.gif
    coexist run --server http://127.0.0.1:8000 --env cooking --ego TomatoLettuceSalad \
        --partners CarrotBanana --episodes 5 --max-steps 400

The ego (agent 0) acts through the server with `--method`; each partner follows its own task
policy, also served (method `sl`, the partner as the ego of its own request), so no model is
needed locally; `--infer` tells the ego no partner goal (the server infers them). Prints
per-agent and team returns (mean ± standard error over episodes), success (its own goal reached
at the end: in its target area, its dish served) and episode length. `services.env_client` runs
the loop on `coexist_client.RemotePolicy`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer


def _client(server: str, transport: str | None) -> Any:
    """A client for `server`, parsed as the SDK parses it (`coexist_client.address`): the
    scheme decides, `--transport` a bare `host:port` (REST without it)."""
    from coexist_client import Client

    try:
        return Client(server, protocol=transport)  # type: ignore[arg-type]  # checked by run
    except ValueError as err:
        raise typer.BadParameter(str(err), param_hint="--server") from None


def run(
    server: Annotated[
        str,
        typer.Option(
            help="Server: http(s)://host:port (REST), grpc(s)://host:port, or host:port "
            "(REST, or --transport grpc)."
        ),
    ] = "http://127.0.0.1:8000",
    env: Annotated[str, typer.Option(help="Environment: particle or cooking.")] = "particle",
    ego: Annotated[str, typer.Option(help="The ego agent's goal (agent 0).")] = "a2",
    partners: Annotated[
        str, typer.Option(help="Comma-separated partner goals (agents 1..N-1).")
    ] = "b3",
    method: Annotated[
        str,
        typer.Option(help="Ego method: aail_bounded, aail_budget, aail, nail, sl or jl."),
    ] = "aail_bounded",
    regret_bound: Annotated[
        float | None,
        typer.Option(
            min=0.0,
            help="aail_bounded's ε (default: twice the task network's training α).",
        ),
    ] = None,
    budget: Annotated[
        float | None,
        typer.Option(
            min=0.0,
            help="aail_budget's episode budget of the ego's own task value, in the task "
            "network's Q units (default: 8 times its training α).",
        ),
    ] = None,
    infer: Annotated[
        bool, typer.Option(help="Announce no partner goal: the server infers them.")
    ] = False,
    episodes: Annotated[int, typer.Option(min=1, help="Number of episodes.")] = 20,
    seed: Annotated[int, typer.Option(min=0, help="Seed of start states and sampling.")] = 0,
    max_steps: Annotated[int, typer.Option(min=1, help="Steps before truncation.")] = 200,
    transport: Annotated[
        str | None, typer.Option(help="http or grpc (default: from the URL's scheme).")
    ] = None,
    gif: Annotated[Path | None, typer.Option(help="Render the first episode to this GIF.")] = None,
    greedy: Annotated[bool, typer.Option(help="Act greedily instead of sampling.")] = False,
    alias: Annotated[str, typer.Option(help="Model alias to serve from.")] = "production",
) -> None:
    """Run episodes where the ego acts through the server and partners follow their task policy."""
    from coexist_client import CoexistError
    from rich.console import Console
    from rich.markup import escape
    from rich.progress import Progress
    from rich.table import Table

    from envs.particle.render import save_gif
    from services.env_client import run_episodes, summarise

    if transport not in (None, "http", "grpc"):
        raise typer.BadParameter("expected http or grpc", param_hint="--transport")
    partner_goals = [g.strip() for g in partners.split(",") if g.strip()]
    console = Console()
    client = _client(server, transport)
    try:
        with Progress(console=console, transient=True) as progress:
            task = progress.add_task(f"{episodes} episodes", total=episodes)
            results = run_episodes(
                client,
                env=env,
                ego_goal=ego,
                partner_goals=partner_goals,
                method=method,
                regret_bound=regret_bound,
                budget=budget,
                infer=infer,
                episodes=episodes,
                seed=seed,
                max_steps=max_steps,
                alias=alias,
                greedy=greedy,
                record_first=gif is not None,
                on_episode=lambda _: progress.advance(task),
            )
    except (CoexistError, ValueError) as err:
        console.print(f"[red]error:[/red] {escape(str(err))}")
        raise typer.Exit(1) from None
    finally:
        client.close()

    summary = summarise(results)
    goals = results[0].goals
    table = Table(title=f"{env}: {len(results)} episodes, ego {method}, seed {seed} ({server})")
    for column, justify in (
        ("agent", "left"),
        ("goal", "left"),
        ("policy", "left"),
        ("return (mean ± se)", "right"),
        ("success", "right"),
    ):
        table.add_column(column, justify=justify)  # type: ignore[arg-type]
    for i, goal in enumerate(goals):
        policy = (method + (", goals inferred" if infer else "")) if i == 0 else "sl (own task)"
        name = f"agent_{i}" + (" (ego)" if i == 0 else "")
        rate = f"{summary.success_rate[i]:.0%}"
        table.add_row(name, goal, policy, str(summary.returns[i]), rate)
    table.add_row("team", "", "", str(summary.team_return), "", style="bold")
    console.print(table)
    console.print(f"episode length: {summary.length} steps (max {max_steps})")
    if gif is not None:
        gif.parent.mkdir(parents=True, exist_ok=True)
        save_gif(results[0].frames, gif)
        console.print(f"wrote {gif} ({len(results[0].frames)} frames, episode 0)")
