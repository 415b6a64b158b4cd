"""Trainer throughput: stacked (batched) soft-Q updates vs one network at a time, with the
float32 GFLOP/s they reach beside this core's measured matmul peak, env steps per second during
training, and (with --zoo) the wall time of the whole particle zoo.

    .venv/bin/python benchmarks/training.py            # updates/s and training steps/s (~1 min)
    .venv/bin/python benchmarks/training.py --zoo      # + 35 task + 35 impact networks (minutes)

Timings are medians of repeats; the batched/sequential ratio is measured in the same run. The
peak is a square float32 matmul (1024 x 1024) on the same number of torch threads; an update's
FLOPs are counted from its matmuls (`update_flops`), the element-wise work is not counted.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

import torch
from machine import describe
from rich.console import Console
from rich.table import Table

from policy.qnet import QNetSpec
from trainer.config import ImpactConfig, TaskConfig
from trainer.learners import all_goals, train_impacts, train_tasks
from trainer.replay import Batch
from trainer.soft_q import StackedSoftQ


def _batch(n_nets: int, size: int, gen: torch.Generator) -> Batch:
    return Batch(
        obs_GBD=torch.rand(n_nets, size, 8, generator=gen),
        act_GB=torch.randint(0, 5, (n_nets, size), generator=gen),
        rew_GB=-torch.rand(n_nets, size, generator=gen),
        next_obs_GBD=torch.rand(n_nets, size, 8, generator=gen),
    )


def update_flops(spec: QNetSpec, batch_size: int) -> int:
    """Multiply-adds x 2 of one network's soft-Q update on `batch_size` samples: the target
    network's forward on s', the online forward on s, and the backward's weight gradients of
    every layer and input gradients of every layer but the first (`trainer.soft_q`)."""
    per_layer = [n_in * n_out for n_in, n_out in spec.layer_sizes]
    return 2 * batch_size * (3 * sum(per_layer) + sum(per_layer[1:]))


def matmul_peak_gflops(seconds: float, size: int = 1024) -> float:
    """float32 GFLOP/s of a square matmul on this process's torch threads."""
    a, b = torch.rand(size, size), torch.rand(size, size)
    a @ b  # warm-up
    rounds, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        a @ b
        rounds += 1
    return rounds * 2 * size**3 / (time.perf_counter() - start) / 1e9


def updates_per_second(n_nets: int, stacked: bool, seconds: float, cfg: TaskConfig) -> float:
    """Network-updates per second for `n_nets` networks, stacked in one learner or one by one."""
    gen = torch.Generator().manual_seed(0)
    spec = QNetSpec(obs_dim=8, n_actions=5, hidden=cfg.hidden)
    groups = [n_nets] if stacked else [1] * n_nets
    learners = [
        StackedSoftQ(spec, g, lr=cfg.lr, gamma=cfg.gamma, alpha=cfg.alpha, generator=gen)
        for g in groups
    ]
    batches = [_batch(g, cfg.batch_size, gen) for g in groups]
    rounds, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for learner, batch in zip(learners, batches, strict=True):
            learner.update(batch)
        rounds += 1
    return rounds * n_nets / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--zoo", action="store_true", help="also time the whole particle zoo")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (see README)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    cfg = TaskConfig()
    console = Console()
    spec = QNetSpec(obs_dim=8, n_actions=5, hidden=cfg.hidden)
    gflop = update_flops(spec, cfg.batch_size) / 1e9
    peak = statistics.median(matmul_peak_gflops(args.seconds) for _ in range(args.repeats))
    table = Table(title=f"soft-Q updates (MLP {cfg.hidden}, batch {cfg.batch_size} per network)")
    for col in ("networks", "how", "network-updates/s (median)", "speed-up", "GFLOP/s", "of peak"):
        table.add_column(col, justify="right")

    def row(n_nets: int, how: str, rate: float, base: float) -> None:
        achieved = rate * gflop
        speed_up, share = f"{rate / base:.1f}x", f"{achieved / peak:.0%}"
        table.add_row(str(n_nets), how, f"{rate:,.0f}", speed_up, f"{achieved:.1f}", share)

    for n_nets in (1, 35):
        seq = statistics.median(
            updates_per_second(n_nets, False, args.seconds, cfg) for _ in range(args.repeats)
        )
        row(n_nets, "one at a time", seq, seq)
        if n_nets > 1:
            stk = statistics.median(
                updates_per_second(n_nets, True, args.seconds, cfg) for _ in range(args.repeats)
            )
            row(n_nets, "stacked", stk, seq)
    console.print(describe())
    console.print(table)
    console.print(
        f"float32 matmul peak ({args.threads} torch thread(s), 1024 x 1024): {peak:.1f} GFLOP/s; "
        f"one network-update = {gflop * 1e3:.2f} MFLOP"
    )

    steps = 300
    short = replace(cfg, total_steps=steps, warmup_steps=50)
    start = time.perf_counter()
    train_tasks(all_goals(), short, seed=0, evaluate=False)
    elapsed = time.perf_counter() - start
    transitions = steps * short.envs_per_net * 35
    console.print(
        f"training 35 task networks: {transitions / elapsed:,.0f} env steps/s "
        f"({transitions:,} transitions in {elapsed:.1f} s, updates included)"
    )
    if args.zoo:
        start = time.perf_counter()
        tasks = train_tasks(all_goals(), cfg, seed=0)
        t_tasks = time.perf_counter() - start
        start = time.perf_counter()
        train_impacts(all_goals(), tasks.nets, ImpactConfig(), seed=1)
        t_impacts = time.perf_counter() - start
        passed = sum(bool(g and g.passed) for g in tasks.gates)
        console.print(
            f"particle zoo: 35 task networks {t_tasks / 60:.1f} min ({passed}/35 gates passed), "
            f"35 impact networks {t_impacts / 60:.1f} min, total {(t_tasks + t_impacts) / 60:.1f} min"
        )


if __name__ == "__main__":
    main()
