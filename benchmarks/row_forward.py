"""The compiled row forward (`policy._row_forward`) on stacks of Q-networks at the trainer's size,
with the weights hot in the caches and cold (fetched from memory), as a server meets them.

Run: `taskset -c 0 .venv/bin/python benchmarks/row_forward.py [--calls 300]`

| case             | members x rows | what serves it                                         |
|------------------|----------------|--------------------------------------------------------|
| 35 x 1           | 35 x 1         | a session's pass over every goal, one partner          |
| 35 x 4           | 35 x 4         | the same, four partners                                |
| 1 x 1024         | 1 x 1024       | a 256-row batch's task network on its 4 views per row  |
| 4 x 256          | 4 x 256        | that batch's 4 impact networks                         |

Each case runs at every vector width this CPU has (8 floats, AVX2; 16, AVX-512F: the same
bits, `policy/_row_forward_layer.h`), so one run shows what the wider vectors are worth.

Hot: the same call back to back. Cold: before each call the benchmark reads a buffer larger than
the last-level cache, so the weights come from memory, which is how a server meets a session's
stack of 35 networks: between two steps of a session its other work (parsing, answers, the other
stack) and other processes evict them. Each figure is the median of `--calls` calls (the
buffer's reading not timed), with the weights' bytes per second and the multiply-adds' GFLOP/s.
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from machine import describe, last_level_cache_bytes

from policy.row_forward import COMPILED, row_forward, vector_widths
from trainer.config import TaskConfig

PAIR_OBS_DIM, N_ACTIONS = 8, 5  # the particle world's pair view and actions
CASES = ((35, 1), (35, 4), (1, 1024), (4, 256))
# the cold case reads 1.5x the last-level cache (at least this) before each call: the kinds of
# machine measured differ several-fold in L3 size, and a fixed size left the weights in the larger
MIN_EVICT_BYTES = 64 * 2**20

Layers = list[tuple[np.ndarray, np.ndarray]]


def stack(rng: np.random.Generator, members: int) -> Layers:
    """`members` random networks of the trainer's sizes, laid out as the engine stacks them."""
    sizes = (PAIR_OBS_DIM, *TaskConfig().hidden, N_ACTIONS)
    return [
        (
            (rng.standard_normal((members, n_in, n_out)) / np.sqrt(n_in)).astype(np.float32),
            np.zeros((members, 1, n_out), dtype=np.float32),
        )
        for n_in, n_out in itertools.pairwise(sizes)
    ]


def median_us(call: Callable[[], object], calls: int, before: Callable[[], object]) -> float:
    """Median µs of `call`, `before` run (untimed) ahead of each."""
    for _ in range(10):
        before()
        call()
    times = []
    for _ in range(calls):
        before()
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--calls", type=int, default=300)
    args = parser.parse_args()
    if not COMPILED:
        raise SystemExit("no compiled row forward on this machine: nothing to measure")
    rng = np.random.default_rng(0)
    evict = np.ones(max(MIN_EVICT_BYTES, 3 * (last_level_cache_bytes() or 0) // 2) // 8)
    widths = vector_widths()
    print(describe())
    print(
        "| members x rows | lanes | hot µs | cold µs | cold / hot | cold weights GB/s | hot GFLOP/s |"
    )
    print("|---|---|---|---|---|---|---|")
    for members, rows in CASES:
        layers = stack(rng, members)
        x = rng.standard_normal((1, rows, PAIR_OBS_DIM)).astype(np.float32)
        weight_bytes = sum(w.nbytes + b.nbytes for w, b in layers)
        flops = 2 * rows * sum(w.size for w, _ in layers)
        for lanes in widths:

            def forward(
                x: np.ndarray = x,
                layers: Layers = layers,
                members: int = members,
                lanes: int = lanes,
            ) -> object:
                return row_forward(x, layers, 0, members, "relu", lanes=lanes)

            hot = median_us(forward, args.calls, lambda: None)
            cold = median_us(forward, args.calls, evict.sum)
            print(
                f"| {members} x {rows} | {lanes} | {hot:.0f} | {cold:.0f} | {cold / hot:.2f} | "
                f"{weight_bytes / cold / 1e3:.1f} | {flops / hot / 1e3:.1f} |"
            )


if __name__ == "__main__":
    main()
