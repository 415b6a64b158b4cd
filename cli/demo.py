"""`coexist demo`: one episode of the particle world, rendered to a GIF (and its last frame to PNG).

The agents follow the scripted straight-to-target controller (no trained networks needed), so the
demo shows the world, the goals' target areas (filled) and influence areas (hollow).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer


def _frame(env: Any) -> Any:
    frame = env.render()
    assert frame is not None, "render_mode='rgb_array' always returns a frame"
    return frame


def demo(
    out: Annotated[
        Path, typer.Option(help="Where to write the GIF; a PNG of the last frame goes beside it.")
    ] = Path("demo/particle.gif"),
    goals: Annotated[
        str, typer.Option(help="Comma-separated goal ids, one per agent (1 to 5).")
    ] = "a2,b3",
    seed: Annotated[int, typer.Option(help="Seed of the start positions.")] = 0,
    steps: Annotated[int, typer.Option(min=1, help="Maximum number of steps.")] = 120,
) -> None:
    """Run a demo episode of the coexistence particle world and render it."""
    import numpy as np
    from PIL import Image
    from rich.console import Console
    from rich.table import Table

    from envs.particle.env import ParticleCoexistenceEnv
    from envs.particle.goals import goal_index
    from envs.particle.render import save_gif
    from envs.particle.scripted import scripted_actions

    goal_ids = [g.strip() for g in goals.split(",") if g.strip()]
    try:
        env = ParticleCoexistenceEnv(goals=goal_ids, max_steps=steps, render_mode="rgb_array")
    except ValueError as err:
        raise typer.BadParameter(str(err), param_hint="--goals") from None
    goals_N = np.array([goal_index(g) for g in goal_ids])
    env.reset(seed=seed)
    frames = [_frame(env)]
    returns = dict.fromkeys(env.possible_agents, 0.0)
    length = 0
    while env.agents:
        state_N4 = env.state().reshape(len(goal_ids), 4)
        acts = scripted_actions(state_N4[None], goals_N[None])[0]
        _, rewards, _, _, _ = env.step({a: int(acts[i]) for i, a in enumerate(env.agents)})
        for agent, r in rewards.items():
            returns[agent] += float(r)
        frames.append(_frame(env))
        length += 1
    out.parent.mkdir(parents=True, exist_ok=True)
    save_gif(frames, out)
    png = out.with_suffix(".png")
    Image.fromarray(frames[-1]).save(png)

    table = Table(title=f"particle world, {length} steps, seed {seed}")
    table.add_column("agent")
    table.add_column("goal")
    table.add_column("return", justify="right")
    for agent, goal in zip(env.possible_agents, goal_ids, strict=True):
        table.add_row(agent, goal, f"{returns[agent]:.2f}")
    table.add_row("team", "", f"{sum(returns.values()):.2f}", style="bold")
    console = Console()
    console.print(table)
    console.print(f"wrote {out} ({len(frames)} frames) and {png}")
