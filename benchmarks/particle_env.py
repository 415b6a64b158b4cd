"""Throughput of the particle world: agent-steps per second (random actions, rewards included).

Run: `.venv/bin/python benchmarks/particle_env.py [--repeats 5]`

| case                      | what is timed per step                                           |
|---------------------------|------------------------------------------------------------------|
| pettingzoo, N = 2 / 5     | `ParticleCoexistenceEnv.step` with a dict of actions (1 env)     |
| batched 1 × 2             | `BatchedParticleWorld.step` + `reset_where` with one world       |
| batched 1024 × 2          | the same with 1024 worlds of 2 agents                            |

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

from envs.particle.batched import BatchedParticleWorld
from envs.particle.env import ParticleCoexistenceEnv
from envs.particle.scenarios import FIVE_AGENTS, NON_ALIGNED_PAIR


def pettingzoo_case(goals: tuple[str, ...], steps: int) -> Callable[[], float]:
    def run() -> float:
        env = ParticleCoexistenceEnv(goals=goals, max_steps=1000)
        actions = np.random.default_rng(0).integers(0, 5, size=(steps, len(goals))).tolist()
        env.reset(seed=0)
        start = time.perf_counter()
        for row in actions:
            if not env.agents:
                env.reset()
            env.step(dict(zip(env.possible_agents, row, strict=True)))
        return steps * len(goals) / (time.perf_counter() - start)

    return run


def batched_case(n_envs: int, steps: int) -> Callable[[], float]:
    def run() -> float:
        world = BatchedParticleWorld(np.array([[3, 18]] * n_envs), max_steps=1000, seed=0)
        actions = np.random.default_rng(0).integers(0, 5, size=(steps, n_envs, 2))
        world.reset()
        start = time.perf_counter()
        for act in actions:
            res = world.step(act)
            world.reset_where(res.terminated_B | res.truncated_B)
        return steps * n_envs * 2 / (time.perf_counter() - start)

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per case (median)")
    args = parser.parse_args()
    ego, partners = FIVE_AGENTS
    cases = {
        "pettingzoo, 1 env x 2 agents": pettingzoo_case(NON_ALIGNED_PAIR, 3000),
        "pettingzoo, 1 env x 5 agents": pettingzoo_case((ego, *partners), 2000),
        "batched, 1 env x 2 agents": batched_case(1, 5000),
        "batched, 1024 envs x 2 agents": batched_case(1024, 300),
    }
    table = Table(title=f"particle world throughput (median of {args.repeats})")
    table.add_column("case")
    table.add_column("agent-steps/s", justify="right")
    table.add_column("min .. max", justify="right")
    for name, run in cases.items():
        rates = [run() for _ in range(args.repeats)]
        table.add_row(
            name, f"{statistics.median(rates):,.0f}", f"{min(rates):,.0f} .. {max(rates):,.0f}"
        )
    Console().print(table)


if __name__ == "__main__":
    main()
