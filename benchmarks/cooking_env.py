"""Throughput of the cooking world: env-steps per second (random actions, 2 cooks, rewards and
observations included; an env-step advances one kitchen by one step for both cooks).

Run: `.venv/bin/python benchmarks/cooking_env.py [--repeats 5] [--layout open]`

| case                   | what is timed per step                                             |
|------------------------|--------------------------------------------------------------------|
| pettingzoo, 1 env      | `CookingEnv.step` with a dict of actions                           |
| batched, 1 env         | `BatchedCookingWorld.step` + `reset_where` with one kitchen        |
| batched, 256 / 1024    | the same with 256 / 1024 kitchens                                  |
| batched, 256 + sub-goals | 256 kitchens with sub-goal rewards (recipe progress every step)  |
| scripted cooks, 1 env  | `scripted_actions` for two planning cooks (no env step)            |

Each case runs `repeats` times; the table shows the median (and the spread, min..max).
Actions are drawn up front so the generator is not timed; finished episodes are reset.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
from rich.console import Console
from rich.table import Table

from envs.cooking.batched import BatchedCookingWorld
from envs.cooking.env import CookingEnv
from envs.cooking.scripted import ScriptedCook, scripted_actions

RECIPES = ("TomatoLettuceSalad", "CarrotBanana")


def pettingzoo_case(layout: str, steps: int) -> Callable[[], float]:
    def run() -> float:
        env = CookingEnv(layout=layout, recipes=RECIPES)
        actions = np.random.default_rng(0).integers(0, 5, size=(steps, 2)).tolist()
        env.reset(seed=0)
        start = time.perf_counter()
        for row in actions:
            if not env.agents:
                env.reset()
            env.step(dict(zip(env.possible_agents, row, strict=True)))
        return steps / (time.perf_counter() - start)

    return run


def batched_case(
    layout: str, n_envs: int, steps: int, sub_goals: float = 0.0
) -> Callable[[], float]:
    def run() -> float:
        world = BatchedCookingWorld(
            layout, np.array([RECIPES] * n_envs), seed=0, sub_goal_reward=sub_goals
        )
        actions = np.random.default_rng(0).integers(0, 5, size=(steps, n_envs, 2))
        world.reset()
        start = time.perf_counter()
        for act in actions:
            res = world.step(act)
            world.reset_where(res.terminated_B | res.truncated_B)
        return steps * n_envs / (time.perf_counter() - start)

    return run


def scripted_case(layout: str, steps: int) -> Callable[[], float]:
    def run() -> float:
        world = BatchedCookingWorld(layout, np.array([RECIPES]), seed=0)
        cooks = [ScriptedCook(RECIPES[0], handover="carrot"), ScriptedCook(RECIPES[1])]
        world.reset()
        start = time.perf_counter()
        for _ in range(steps):
            res = world.step(scripted_actions(world.layout, world.state, cooks))
            world.reset_where(res.terminated_B | res.truncated_B)
        return steps / (time.perf_counter() - start)

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per case (median)")
    parser.add_argument("--layout", default="coexistence", help="built-in layout to time")
    args = parser.parse_args()
    cases = {
        "pettingzoo, 1 env": pettingzoo_case(args.layout, 2000),
        "batched, 1 env": batched_case(args.layout, 1, 2000),
        "batched, 256 envs": batched_case(args.layout, 256, 200),
        "batched, 1024 envs": batched_case(args.layout, 1024, 100),
        "batched, 256 envs + sub-goals": batched_case(args.layout, 256, 200, sub_goals=1.0),
        "scripted cooks + batched, 1 env": scripted_case(args.layout, 300),
    }
    table = Table(title=f"cooking world throughput, {args.layout} (median of {args.repeats})")
    table.add_column("case")
    table.add_column("env-steps/s", justify="right")
    table.add_column("min .. max", justify="right")
    for name, run in cases.items():
        rates = [run() for _ in range(args.repeats)]
        table.add_row(
            name, f"{statistics.median(rates):,.0f}", f"{min(rates):,.0f} .. {max(rates):,.0f}"
        )
    Console().print(table)


if __name__ == "__main__":
    main()
