"""What the C row forward is worth: an act's and a session step's latency with it, and with its
numpy reference instead, in-process. (The blend and the belief kernels are numba, one
implementation each, with nothing to switch: `policy.blend_kernel`, `policy.belief_kernel`.)

Run: `OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/kernels.py [--calls 1500]`

| kernel  | C file                  | numpy reference instead                                |
|---------|-------------------------|--------------------------------------------------------|
| forward | `policy/_row_forward.c` | `policy.row_forward.numpy_row_forward` (stacked matmul)|

Cases: a single act with 1 and with 4 announced partners (AAIL), a 256-row batch with 4, and a
session step with 1 and with 4 inferred partners (its `prepare_next` included: a closed-loop
client waits for it), on the session benchmarks' store (every particle network, random weights
at the trainer's size, `benchmarks/session_scene.py`). The variants run call by call in turn
(all compiled, then each kernel off), so a burst of load from a neighbour on a shared machine
hits all of them alike; each figure is the median of `--calls` calls. A kernel whose numpy
reference costs less than 10 % more on every case is not worth its C.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from machine import describe  # noqa: E402
from session_scene import EGO_GOAL, PARTNER_GOALS, build_store, episode  # noqa: E402

from services.engine.networks import ROW_FORWARD  # noqa: E402  (whether the C forward is built)

VARIANTS = ("all compiled", "forward")
Call = Callable[[int], object]


def cases(url: str, variant: str) -> dict[str, tuple[Call, int]]:
    """The module docstring's cases, each with its share of the calls (batches: a tenth), on
    an engine with the C forward, or (`variant` "forward") its numpy reference."""
    from model_store.sql import SqlModelStore
    from services.engine import ActRequest, InferenceEngine, PartnerSpec
    from services.sessions.messages import Observed, SessionPartner, SessionSettings
    from services.sessions.session import Session

    engine = InferenceEngine(SqlModelStore(url), numpy_forward=variant == "forward")
    out: dict[str, tuple[Call, int]] = {}
    for n in (1, 4):
        obs_TD, actions_TP = episode(n + 1, 200)
        partners = tuple(PartnerSpec(j + 1, goal=g) for j, g in enumerate(PARTNER_GOALS[:n]))

        def act(i: int, obs_TD: np.ndarray = obs_TD, partners: tuple = partners) -> object:
            request = ActRequest("particle", EGO_GOAL, obs_TD[i % 200][None], partners, "aail")
            return engine.act(request)

        out[f"act, {n} announced"] = (act, 10)
        if n == 4:
            batch = ActRequest("particle", EGO_GOAL, obs_TD[np.arange(256) % 200], partners, "aail")

            def columns(i: int, request: ActRequest = batch) -> object:
                return engine.act_columns(request)

            out["batch of 256, 4 announced"] = (columns, 1)
        inferred = tuple(SessionPartner(j + 1, infer=True) for j in range(n))
        session = Session(engine, SessionSettings("particle", EGO_GOAL, inferred), prefetch=True)
        session.step(obs_TD[0])

        def step(
            i: int,
            s: Session = session,
            n: int = n,
            obs: np.ndarray = obs_TD,
            actions: np.ndarray = actions_TP,
        ) -> object:
            t = i % (len(obs) - 1) + 1
            s.prepare_next()
            observed = [Observed(j + 1, int(actions[t - 1, j])) for j in range(n)]
            return s.step(obs[t], observed=observed)

        out[f"session step, {n} inferred"] = (step, 10)
    return out


def measure(calls: int) -> dict[str, dict[str, float]]:
    """Median µs per case and variant."""
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{tmp}/models.db"
        build_store(url)
        found: dict[str, dict[str, float]] = {}
        by_variant = {variant: cases(url, variant) for variant in VARIANTS}
        for name, (_, share) in by_variant[VARIANTS[0]].items():
            times: dict[str, list[float]] = {v: [] for v in VARIANTS}
            for i in range(-20, max(20, calls * share // 10)):  # 20 warm-up rounds
                for variant in VARIANTS:
                    call = by_variant[variant][name][0]
                    start = time.perf_counter()
                    call(i)
                    if i >= 0:
                        times[variant].append(time.perf_counter() - start)
            found[name] = {v: statistics.median(t) * 1e6 for v, t in times.items()}
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--calls", type=int, default=1500, help="timed calls per case (batch: /10)")
    args = parser.parse_args()
    print(describe())
    if not ROW_FORWARD:
        print("no C forward built here: both columns run numpy's")
    print("| case | C forward | forward in numpy |")
    print("|---|---|---|")
    for name, row in measure(args.calls).items():
        base = row["all compiled"]
        cells = [f"{row[v]:.0f} µs ({(row[v] - base) / base * 100:+.0f} %)" for v in VARIANTS[1:]]
        print(f"| {name} | {base:.0f} µs | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
