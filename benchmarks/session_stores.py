"""What keeping a session outside the process costs per step: the in-memory store against the
shared store over Redis and over PostgreSQL, in-process (no transport), on the session
benchmarks' scene (`benchmarks/session_scene.py`: every particle network at the trainer's size,
a seeded episode of five agents, 4 inferred partners, their true actions in `observed`).

Run: `OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/session_stores.py
[--redis redis://127.0.0.1:6379/0] [--postgres postgresql://postgres@127.0.0.1:5432/test]
[--steps 400] [--rounds 3]` (a store left out, or one that does not answer, is skipped).

| case            | what one timed step is                                                     |
|-----------------|----------------------------------------------------------------------------|
| memory          | `SessionStore.step` (the default store)                                    |
| S, same process | `SharedSessionStore.step` where this process served the previous step: the |
|                 | stored version read (one round trip), the step on the process's copy, the  |
|                 | record written by compare-and-set (a second round trip)                    |
| S, alternating  | two store objects taking turns, as two workers or replicas do: each step   |
|                 | also reads the record and restores the session from it (decode, no         |
|                 | settings check: cached per process), and scores its evidence itself        |
| codec           | `SessionCodec.encode` + `decode` of one session's record alone             |
| S, round trip   | one bare round trip from Python: Redis `PING`, PostgreSQL `SELECT 1`       |

Every step is followed by `prepare_next` (untimed), as the servers run it after the answer.
The answers of every case are checked equal to the memory store's (the same seeds). Figures:
the median over rounds of each round's p50 and p99 in ms, the overhead = the case's p50 minus
memory's p50 in the same round, and this process's CPU per step (the step and `prepare_next`,
creation amortised; waiting on the store is not CPU).
"""

from __future__ import annotations

import argparse
import secrets
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from session_scene import PARTNER_GOALS, build_store, episode  # noqa: E402

from model_store.sql import SqlModelStore  # noqa: E402
from services.engine import InferenceEngine  # noqa: E402
from services.sessions import (  # noqa: E402
    Observed,
    Session,
    SessionPartner,
    SessionSettings,
    SessionStore,
    SessionStoreUnavailable,
    SharedSessionStore,
)
from services.sessions.backends import open_backend  # noqa: E402
from services.sessions.codec import SessionCodec, settings_json  # noqa: E402

N_PARTNERS = len(PARTNER_GOALS)
SETTINGS = SessionSettings(
    "particle",
    "a2",
    tuple(SessionPartner(i + 1, infer=True) for i in range(N_PARTNERS)),
    seed=7,
)


def run(
    stores: list[Any], obs_TD: np.ndarray, act_TP: np.ndarray
) -> tuple[list[float], list, float]:
    """Seconds per step, the answers' probabilities, and this process's CPU seconds per step
    (the step and `prepare_next`, not the time spent waiting on the store), the stores taking
    turns."""
    cpu = time.process_time()
    session_id = stores[0].create(SETTINGS).session_id
    times, probs = [], []
    for t, obs in enumerate(obs_TD):
        observed = [] if t == 0 else [Observed(j + 1, int(a)) for j, a in enumerate(act_TP[t - 1])]
        store = stores[t % len(stores)]
        started = time.perf_counter()
        answer = store.step(session_id, obs.tolist(), observed, expected_step=t)
        times.append(time.perf_counter() - started)
        store.prepare_next(session_id)
        probs.append(list(answer.result.probs))
    stores[0].delete(session_id)
    cpu = (time.process_time() - cpu) / len(obs_TD)
    return times[1:], probs, cpu  # step 0 has no evidence


def codec_seconds(engine: InferenceEngine, obs_TD: np.ndarray, act_TP: np.ndarray) -> float:
    session_id, session = "bench", Session(engine, SETTINGS)
    for t in range(5):
        observed = [] if t == 0 else [Observed(j + 1, int(a)) for j, a in enumerate(act_TP[t - 1])]
        session.step(obs_TD[t].tolist(), observed)
    state = session.export_state()
    codec, written = SessionCodec(secrets.token_bytes(24)), settings_json(SETTINGS)
    record = codec.encode(session_id, written, state)
    started, n = time.perf_counter(), 2000
    for _ in range(n):
        codec.decode(session_id, codec.encode(session_id, written, state))
    print(f"record: {len(record)} bytes")
    return (time.perf_counter() - started) / n


def round_trip_ms(name: str, url: str, n: int = 2000) -> float:
    """p50 of one bare round trip to the store, in ms."""
    if name == "Redis":
        import redis

        client = redis.Redis.from_url(url)
        call: Any = client.ping
    else:
        import psycopg

        conn = psycopg.connect(url, autocommit=True)
        call = lambda: conn.execute("SELECT 1").fetchone()  # noqa: E731
    times = []
    for _ in range(n):
        started = time.perf_counter()
        call()
        times.append(time.perf_counter() - started)
    return float(np.percentile(times, 50)) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--redis", default="redis://127.0.0.1:6379/0")
    parser.add_argument("--postgres", default="postgresql://postgres@127.0.0.1:5432/test")
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()

    obs_TD, act_TP = episode(N_PARTNERS + 1, args.steps, seed=3)
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{Path(tmp) / 'models.db'}"
        print(f"networks {build_store(url)}, {args.steps} steps, {N_PARTNERS} inferred partners")
        with SqlModelStore(url) as model_store:
            engine = InferenceEngine(model_store)
            codec = SessionCodec(secrets.token_bytes(24))
            cases: dict[str, list[Any]] = {"memory": [SessionStore(engine)]}
            trips: dict[str, str] = {}
            for name, store_url in (("Redis", args.redis), ("PostgreSQL", args.postgres)):
                make = [
                    SharedSessionStore(engine, open_backend(store_url, codec.namespace()), codec)
                    for _ in range(2)
                ]
                try:
                    len(make[0])
                except SessionStoreUnavailable as err:
                    print(f"skipped {name}: {err}")
                    continue
                cases[f"{name}, same process"] = make[:1]
                cases[f"{name}, alternating"] = make
                trips[name] = store_url
            run(cases["memory"], obs_TD[:20], act_TP)  # warm-up: compile, load, stack
            p50: dict[str, list[float]] = {k: [] for k in cases}
            p99: dict[str, list[float]] = {k: [] for k in cases}
            over: dict[str, list[float]] = {k: [] for k in cases}
            cpu: dict[str, list[float]] = {k: [] for k in cases}
            for _ in range(args.rounds):
                reference: list | None = None
                for name, stores in cases.items():
                    times, probs, cpu_s = run(stores, obs_TD, act_TP)
                    cpu[name].append(cpu_s * 1e3)
                    if reference is None:
                        reference = probs
                    elif probs != reference:
                        raise SystemExit(f"{name}: answers differ from the memory store's")
                    p50[name].append(float(np.percentile(times, 50)) * 1e3)
                    p99[name].append(float(np.percentile(times, 99)) * 1e3)
                    over[name].append(p50[name][-1] - p50["memory"][-1])
            print("\n| case | step p50 ms | step p99 ms | overhead p50 ms | CPU ms/step |")
            print("|---|---|---|---|---|")
            for name in cases:
                print(
                    f"| {name} | {statistics.median(p50[name]):.3f} | "
                    f"{statistics.median(p99[name]):.3f} | {statistics.median(over[name]):+.3f} | "
                    f"{statistics.median(cpu[name]):.3f} |"
                )
            print(
                f"| codec (encode + decode) | {codec_seconds(engine, obs_TD, act_TP) * 1e3:.3f} "
                "| | | |"
            )
            for name, store_url in trips.items():
                print(f"| {name}, round trip | {round_trip_ms(name, store_url):.3f} | | | |")


if __name__ == "__main__":
    main()
