"""Where a session step's time goes, in-process (no transport): the parts of
`benchmarks/session_bench.py`'s REST cases, timed on the same store and the same episode.

Run: `OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/session_breakdown.py --store URL`
(session_bench.py runs it on its temporary store and puts the table in its report).

| part                          | call                                                         |
|-------------------------------|--------------------------------------------------------------|
| act, 1 announced              | `engine.act`, AAIL, partner 1 announced (`b3`)               |
| likelihood pass               | `engine.goal_log_likelihoods`: 35 task networks, 1 partner   |
| act, all 35 blended           | `engine.act` with `goal_probs` over all 35 goals             |
| session step                  | `Session.step` (server defaults) with the partner's previous |
|                               | action: likelihood pass, belief update, act                  |
| act, a fixed 8-goal blend     | `engine.act` with the same 8-goal `goal_probs` every call    |
| session step, top-8 blend     | `Session.step`, `blend_mass` 0.99 and `blend_max_goals` 8    |
| act, top-8 sets of a session  | `engine.act` cycling through the 8-goal sets that session    |
|                               | blended on the episode (they change as the belief moves:     |
|                               | every new set is a new stacked group)                        |

Each part: median of `calls` calls after 100 warm-up calls.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from envs.particle.goals import GOAL_IDS  # noqa: E402


def _median_ms(call: Callable[[int], object], calls: int) -> float:
    for i in range(100):
        call(i)
    times = []
    for i in range(calls):
        start = time.perf_counter()
        call(i)
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3


def breakdown(url: str, obs_TD: np.ndarray, actions_TP: np.ndarray, calls: int) -> dict[str, float]:
    """Median milliseconds of every part of the module docstring (2-agent episode)."""
    from model_store.sql import SqlModelStore
    from services.engine import ActRequest, InferenceEngine, PartnerSpec
    from services.sessions.messages import Observed, SessionPartner, SessionSettings
    from services.sessions.session import Session

    engine = InferenceEngine(SqlModelStore(url))
    steps = len(obs_TD)

    def act(goal_probs: dict[str, float] | None, i: int) -> object:
        spec = (
            PartnerSpec(1, goal="b3")
            if goal_probs is None
            else PartnerSpec(1, goal_probs=goal_probs)
        )
        return engine.act(ActRequest("particle", "a2", obs_TD[i % steps][None], (spec,)))

    def session(mass: float = 1.0, most: int | None = None) -> Callable[[int], object]:
        partners = (SessionPartner(1, infer=True),)
        settings = SessionSettings(
            "particle", "a2", partners, blend_mass=mass, blend_max_goals=most
        )
        s = Session(engine, settings)
        s.step(obs_TD[0])
        sets.clear()

        def step(i: int) -> object:
            t = i % (steps - 1) + 1
            result = s.step(obs_TD[t], observed=[Observed(1, int(actions_TP[t - 1, 0]))])
            sets.add(tuple(m.goal for m in result.result.models if m.role == "impact"))
            return result

        return step

    sets: set[tuple[str, ...]] = set()
    out = {"act, 1 announced": _median_ms(lambda i: act(None, i), calls)}
    out["likelihood pass"] = _median_ms(
        lambda i: engine.goal_log_likelihoods(
            "particle", obs_TD[i % steps], [1], [int(actions_TP[i % steps, 0])]
        ),
        calls,
    )
    everything = {g: 1 / len(GOAL_IDS) for g in GOAL_IDS}
    out["act, all 35 blended"] = _median_ms(lambda i: act(everything, i), calls)
    out["session step"] = _median_ms(session(), calls)
    fixed = {g: 1 / 8 for g in GOAL_IDS[:8]}
    out["act, a fixed 8-goal blend"] = _median_ms(lambda i: act(fixed, i), calls)
    out["session step, top-8 blend"] = _median_ms(session(mass=0.99, most=8), calls)
    seen = [{g: 1 / len(s) for g in s} for s in sorted(sets)]
    out[f"act, top-8 sets of that session ({len(seen)} distinct)"] = _median_ms(
        lambda i: act(seen[i % len(seen)], i), calls
    )
    return out


def main() -> None:
    from session_bench import episode

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--store", required=True, help="a store with every particle network")
    parser.add_argument("--calls", type=int, default=1000)
    args = parser.parse_args()
    obs_TD, actions_TP = episode(2, 200)
    for name, ms in breakdown(args.store, obs_TD, actions_TP, args.calls).items():
        print(f"| {name} | {ms:.3f} |")


if __name__ == "__main__":
    main()
