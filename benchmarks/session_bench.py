"""Session step latency: a REST step with goal inference against a plain `/v1/act`.

Run: `.venv/bin/python benchmarks/session_bench.py [--duration 5] [--rounds 3] [--steps 200] [--no-prefetch]
[--out reports/inference]` (needs `wrk` and `taskset`; the plumbing is `benchmarks/wrk_server.py`).

| case                         | request per step                                     | networks per step    |
|------------------------------|------------------------------------------------------|----------------------|
| act, 1 announced             | `POST /v1/act`, AAIL, partner 1's goal announced     | 1 task + 1 impact    |
| step, 1 inferred             | `POST /v1/sessions/{id}/steps`, partner 1 inferred   | 35 task (likelihood) |
|                              | over 35 goals (server defaults), its previous action | + 1 task + 35 impact |
|                              | in `observed`                                        | (the whole belief)   |
| step, 1 inferred, top-8      | the same, the session created with `belief:          | 35 task + 1 task +   |
| blend                        | {blend_mass: 0.99, blend_max_goals: 8}`              | <= 8 impact          |
| step, 1 inferred, no action  | the default session without `observed`: no update    | 1 task + 35 impact   |
| act, 4 announced             | `POST /v1/act`, five agents, 4 announced partners    | 1 task + 4 impact    |
| step, 4 inferred (+ top-8)   | the session, 4 partners inferred, 4 actions a step   | 35 task + 1 + 4 × 35 |

Target: step p50 <= 1.5 × the plain act's p50 (1 partner; 4 partners reported too).

Closed loop and paced. wrk sends each request the moment the previous answer is in (closed
loop: no time between steps) and, in the "paced" cases, `--pause-ms` after it (default 5 ms:
a 200 Hz control loop, faster than most robots step). The difference matters for sessions: the
server scores step t + 1's evidence right after sending step t's answer
(`Session.prepare_next`, ~50 µs), which a paced client never waits for and a closed-loop one
waits for in part (wrk's turnaround hides ~30 µs of it). The act and the step are paced alike.

Why the top-8 case: a blend of the belief's top goals only (99 % of the mass, at most 8; the
sessions' first default) mixes a set of impact networks that changes from step to step as the
belief moves. The engine serves such sets from the stacked group of every goal's network (its
"Goal distributions"), so the case measures what truncating the belief costs beside blending
the whole belief (the default, and the exact belief-weighted blend).

The server is the real one (`coexist serve --no-bootstrap`, uvicorn + uvloop + httptools, one
worker, no gRPC), pinned to CPU 0, on a temporary SQLite store holding ALL 35 particle task and
impact networks at the trainer's size (`TaskConfig().hidden`, random weights, α 0.02). The load
generator is `wrk` pinned to CPU 1, one connection, one thread (c = 1, closed loop); p50 from
`--latency`. Each case warms up for 1 s, then runs `--duration` seconds.

Every request is a valid step of one long session: a Lua script cycles through `--steps`
pre-built bodies, the ego's observations of a seeded particle episode (agents acting at random)
with the partners' true actions in `observed`, so the belief moves as in an episode and the
blend's goal set changes with it; the plain act cycles through the same observations. After
each session case the session's `updates` counter is read back to prove that every timed step
ran the likelihood pass. With random weights the belief stays broad, so the blend mixes the
maximum of 8 impact networks per partner: the worst case for the act part of a step.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import httpx

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from machine import describe  # noqa: E402  (this folder: on sys.path when run as a script)
from session_scene import (  # noqa: E402  (this folder: on sys.path when run as a script)
    EGO_GOAL,
    PARTNER_GOALS,
    act_bodies,
    build_store,
    episode,
    step_bodies,
)
from wrk_server import (  # noqa: E402  (this folder: on sys.path when run as a script)
    LOAD_CPU,
    SERVER_CPU,
    free_port,
    run_wrk,
    start_server,
)

TARGET = 1.5
# a session's belief settings that blend only the belief's top goals (module docstring)
TOP_8 = {"blend_mass": 0.99, "blend_max_goals": 8}


@dataclass
class Case:
    case: str
    requests: int
    seconds: float
    p50_ms: float
    p90_ms: float
    p99_ms: float
    failed: int
    impact_nets: int  # impact networks the last answer blended (from its `models`)
    p50_rounds_ms: list[float]  # each round's p50

    @property
    def rps(self) -> float:
        return self.requests / self.seconds


def impact_count(answer: dict[str, Any]) -> int:
    return sum(1 for m in answer["models"] if m["role"] == "impact")


def open_session(
    client: httpx.Client, n_partners: int, first_body: bytes, belief: dict[str, Any]
) -> str:
    """A session with `n_partners` inferred partners, its step 0 taken (no evidence yet)."""
    partners = [{"index": j + 1, "infer": True} for j in range(n_partners)]
    reply = client.post(
        "/v1/sessions",
        json={
            "env": "particle",
            "ego_goal": EGO_GOAL,
            "partners": partners,
            "method": "aail",
            "belief": belief,
        },
    )
    reply.raise_for_status()
    session_id: str = reply.json()["session_id"]
    body = json.loads(first_body)
    body.pop("observed", None)
    client.post(f"/v1/sessions/{session_id}/steps", json=body).raise_for_status()
    return session_id


Plan = list[tuple[str, str, list[bytes], str | None, dict[str, Any], float]]  # label, path,
# bodies, session id (None: a plain act), one checked answer, wrk's pause after each answer (ms)


def plan_cases(client: httpx.Client, n_partners: int, steps: int, pause_ms: float) -> Plan:
    """The cases of one scene size, each checked with one real request first; the plain act
    and the default step also paced (`pause_ms` between an answer and the next request)."""
    obs_TD, actions_TP = episode(1 + n_partners, steps)
    acts = act_bodies(obs_TD, PARTNER_GOALS[:n_partners])
    reply = client.post("/v1/act", content=acts[-1], headers={"content-type": "application/json"})
    reply.raise_for_status()
    plan: Plan = [(f"act, {n_partners} announced", "/v1/act", acts, None, reply.json(), 0.0)]
    variants: list[tuple[bool, str, dict[str, Any]]] = [
        (True, f"step, {n_partners} inferred", {}),
        (True, f"step, {n_partners} inferred, top-8 blend", TOP_8),
    ]
    if n_partners == 1:
        variants.append((False, "step, 1 inferred, no action", {}))
    for observed, label, belief in variants:
        bodies = step_bodies(obs_TD, actions_TP, observed)
        session_id = open_session(client, n_partners, bodies[0], belief)
        path = f"/v1/sessions/{session_id}/steps"
        step = client.post(path, content=bodies[1], headers={"content-type": "application/json"})
        step.raise_for_status()
        plan.append((label, path, bodies, session_id, step.json(), 0.0))
    if pause_ms > 0:
        plan += [
            (f"{label}, paced", path, bodies, session_id, answer, pause_ms)
            for label, path, bodies, session_id, answer, _ in plan[:2]  # the act, the step
        ]
    return plan


def measure(port: int, duration: float, steps: int, rounds: int, pause_ms: float) -> list[Case]:
    """Every case `rounds` times, interleaved (act, steps, act, steps, ...), so that a change
    of machine load hits every case alike; figures are medians over the rounds."""
    base = f"http://127.0.0.1:{port}"
    runs: dict[str, list[dict[str, float]]] = {}
    with httpx.Client(base_url=base, timeout=30) as client, tempfile.TemporaryDirectory() as tmp:
        plans = [(n, entry) for n in (1, 4) for entry in plan_cases(client, n, steps, pause_ms)]
        for r in range(rounds):
            for n_partners, (label, path, bodies, session_id, _, pause) in plans:
                before = _updates(client, session_id)
                got, sent = run_wrk(base, path, bodies, duration, Path(tmp), pause)
                if session_id is not None and "no action" not in label:
                    # every step updated every partner's belief (wrk may leave one request
                    # per run uncounted at its deadline)
                    gained = (_updates(client, session_id) - before) // n_partners
                    if not sent <= gained <= sent + 2:
                        raise SystemExit(f"{label}: {gained} belief updates for {sent} steps")
                runs.setdefault(label, []).append(got)
                print(
                    f"  round {r + 1}: {label:36} p50 {got['p50_ms']:7.3f} ms  "
                    f"{got['requests'] / got['seconds']:8,.0f} req/s  failed "
                    f"{got['failed']:.0f}",
                    flush=True,
                )
    cases = []
    for _, (label, _, _, _, answer, _) in plans:
        got_runs = runs[label]
        p50, p90, p99 = (statistics.median(g[f"p{q}_ms"] for g in got_runs) for q in (50, 90, 99))
        cases.append(
            Case(
                label,
                int(sum(g["requests"] for g in got_runs)),
                sum(g["seconds"] for g in got_runs),
                p50,
                p90,
                p99,
                int(sum(g["failed"] for g in got_runs)),
                impact_count(answer),
                [g["p50_ms"] for g in got_runs],
            )
        )
    return cases


def _updates(client: httpx.Client, session_id: str | None) -> int:
    """Belief updates so far, summed over the session's partners (0 for no session)."""
    if session_id is None:
        return 0
    reply = client.get(f"/v1/sessions/{session_id}")
    reply.raise_for_status()
    return sum(b["updates"] for b in reply.json()["beliefs"])


def ratios(cases: list[Case]) -> dict[str, float]:
    """Step p50 / act p50 per scene size and blend: the median over rounds of each round's
    ratio (a round's cases ran seconds apart, under the same load)."""
    by = {c.case: c for c in cases}
    out = {}
    for n in (1, 4):
        act = by.get(f"act, {n} announced")
        paced = by.get(f"act, {n} announced, paced")
        for suffix, name, base in (
            ("", "server defaults", act),
            (", top-8 blend", "top-8 blend", act),
            (", paced", "server defaults, paced", paced),
        ):
            step = by.get(f"step, {n} inferred{suffix}")
            if base and step:
                pairs = zip(step.p50_rounds_ms, base.p50_rounds_ms, strict=True)
                key = f"{n} partner{'s' if n > 1 else ''}, {name}"
                out[key] = statistics.median(s / a for s, a in pairs)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=5.0, help="seconds per case")
    parser.add_argument("--steps", type=int, default=200, help="bodies cycled through per case")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved runs of every case")
    parser.add_argument(
        "--no-prefetch",
        action="store_true",
        help="serve with COEXIST_SESSION_PREFETCH=false (steps score their own "
        "evidence: the A/B of scoring ahead)",
    )
    parser.add_argument(
        "--pause-ms",
        type=float,
        default=5.0,
        help="paced cases: wrk waits this long after each answer (0: none)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=ROOT / "reports/inference",
        help="writes latency.json here and re-renders README.md",
    )
    args = parser.parse_args()
    for tool in ("wrk", "taskset"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: apt-get install wrk util-linux")
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{tmp}/models.db"
        size = build_store(url)
        from session_breakdown import breakdown  # this folder is on sys.path when run

        print(describe())
        print("in-process breakdown (this process) ...", flush=True)
        in_process = breakdown(url, *episode(2, args.steps), calls=1000)
        port = free_port()
        os.environ["COEXIST_SESSION_PREFETCH"] = "false" if args.no_prefetch else "true"
        server = start_server(url, port)  # inherits this environment
        try:
            print(
                f"server on CPU {SERVER_CPU}, wrk on CPU {LOAD_CPU}, c=1, {args.duration:g} s "
                "per case"
            )
            cases = measure(port, args.duration, args.steps, args.rounds, args.pause_ms)
        finally:
            server.terminate()
            server.wait(timeout=30)
    print("\n| case | p50 ms | p90 ms | p99 ms | req/s | impact nets | failed |")
    print("|---|---|---|---|---|---|---|")
    for c in cases:
        print(
            f"| {c.case} | {c.p50_ms:.3f} | {c.p90_ms:.3f} | {c.p99_ms:.3f} | {c.rps:,.0f} | "
            f"{c.impact_nets} | {c.failed} |"
        )
    found = ratios(cases)
    for name, ms in in_process.items():
        print(f"in-process: {name}: {ms:.3f} ms")
    for name, ratio in found.items():
        verdict = "met" if ratio <= TARGET else "MISSED"
        print(f"{name}: step p50 / act p50 = {ratio:.2f}x (target <= {TARGET}: {verdict})")
    if any(c.failed for c in cases):
        raise SystemExit("some requests failed: the figures above are not valid")
    command = "python benchmarks/session_bench.py " + " ".join(
        [
            f"--duration {args.duration:g}",
            f"--steps {args.steps}",
            f"--rounds {args.rounds}",
            f"--pause-ms {args.pause_ms:g}",
            *(["--no-prefetch"] if args.no_prefetch else []),
        ]
    )
    setup = (
        f"Real server (`coexist serve`, one uvicorn worker) pinned to CPU {SERVER_CPU}, `wrk` "
        f"(c = 1, one thread) pinned to CPU {LOAD_CPU}; every case {args.rounds} times, "
        f"interleaved, {args.duration:g} s each after 1 s of warm-up (figures: medians over the "
        "rounds; ratios: the median of each round's ratio); temporary SQLite store with all 35 "
        "task and 35 impact networks "
        f"({size} MLPs, random weights); each case cycles through {args.steps} bodies of a "
        "seeded episode, every session step carrying the partners' previous actions; "
        f"the paced cases: wrk waits {args.pause_ms:g} ms after each answer (a control loop "
        "stepping at most every few ms), closed loop otherwise; the server scores each "
        f"step's evidence ahead: {'NO (--no-prefetch)' if args.no_prefetch else 'yes'} "
        "(`COEXIST_SESSION_PREFETCH`); "
        f"{describe()}, shared with other work."
    )
    args.out.mkdir(parents=True, exist_ok=True)
    record = {
        "command": command,
        "setup": setup,
        "target": TARGET,
        "ratios": found,
        "cases": [asdict(c) | {"rps": c.rps} for c in cases],
        "in_process": in_process,
    }
    (args.out / "latency.json").write_text(json.dumps(record, indent=1))
    from evaluation.inference.report import render_readme

    print(f"wrote {args.out / 'latency.json'}; README: {render_readme(args.out)}")


if __name__ == "__main__":
    main()
