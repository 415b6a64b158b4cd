"""Where a session step's time goes, in-process (no transport): the parts of
`benchmarks/session_bench.py`'s REST cases, timed on the same store and the same episode.

Run: `OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/session_breakdown.py --store URL
[--belief-noise ETA]`
(session_bench.py runs it on its temporary store and puts the table in its report).

| part                          | call                                                         |
|-------------------------------|--------------------------------------------------------------|
| act, 1 announced              | `engine.act`, AAIL, partner 1 announced (`b3`)               |
| likelihood pass               | `engine.goal_log_likelihoods`: 35 task networks, 1 partner   |
| act, all 35 blended           | `engine.act` with `goal_probs` over all 35 goals             |
| session step                  | `Session.step` (server defaults) with the partner's previous |
|                               | action: likelihood pass, belief update, act                  |
| session step, scored ahead    | the same, `Session.prepare_next` run (untimed) before each   |
|                               | step, as the servers run it after each answer: the step only |
|                               | picks its action's likelihoods from the table                |
| prepare_next                  | that table: the likelihood pass for every action (untimed    |
|                               | steps in between)                                            |
| act, a fixed 8-goal blend     | `engine.act` with the same 8-goal `goal_probs` every call    |
| session step, top-8 blend     | `Session.step`, `blend_mass` 0.99 and `blend_max_goals` 8    |
| act, top-8 sets of a session  | `engine.act` cycling through the 8-goal sets that session    |
|                               | blended on the episode (they change as the belief moves;     |
|                               | each set seen again stacks its own group)                    |
| REST act, in-process          | `POST /v1/act` (the "act, 1 announced" body) through the     |
|                               | ASGI app of the REST routers, no server and no socket        |
| REST step, in-process         | `POST /v1/sessions/{id}/steps` (server defaults, with the    |
|                               | partner's previous action) the same way                      |

Each part: median of `calls` calls after 100 warm-up calls. The two REST rows minus "act, 1
announced" and "session step" are the routes' own cost (parsing, validation, answer).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable, MutableMapping
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from envs.particle.goals import GOAL_IDS  # noqa: E402


def _timed(call: Callable[[], object]) -> float:
    """Seconds `call` took."""
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def _median_ms(call: Callable[[int], Any], calls: int, timed: bool = False) -> float:
    """Median milliseconds of `call(i)`; `timed`: `call` returns the seconds of its own timed
    part (the rest of it untimed)."""
    for i in range(100):
        call(i)
    times = []
    for i in range(calls):
        start = time.perf_counter()
        took = call(i)
        times.append(took if timed else time.perf_counter() - start)
    return statistics.median(times) * 1e3


def breakdown(
    url: str,
    obs_TD: np.ndarray,
    actions_TP: np.ndarray,
    calls: int,
    belief_noise: float | None = None,
) -> dict[str, float]:
    """Median milliseconds of every part of the module docstring (2-agent episode);
    `belief_noise`: the sessions' `belief.noise` η instead of the default."""
    from model_store.sql import SqlModelStore
    from policy.belief import BeliefConfig
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

    def session(
        mass: float = 1.0, most: int | None = None, ahead: bool = False, timed: str = "step"
    ) -> Callable[[int], object]:
        """One call: a step (`timed` "step"; `ahead`: after an untimed `prepare_next`) or a
        `prepare_next` (`timed` "prepare", after an untimed step)."""
        partners = (SessionPartner(1, infer=True),)
        belief = BeliefConfig() if belief_noise is None else BeliefConfig(noise=belief_noise)
        settings = SessionSettings(
            "particle", "a2", partners, belief=belief, blend_mass=mass, blend_max_goals=most
        )
        s = Session(engine, settings, prefetch=ahead or timed == "prepare")
        s.step(obs_TD[0])
        sets.clear()

        def step(i: int) -> object:
            t = i % (steps - 1) + 1
            result = s.step(obs_TD[t], observed=[Observed(1, int(actions_TP[t - 1, 0]))])
            sets.add(tuple(m.goal for m in result.result.models if m.role == "impact"))
            return result

        if timed == "prepare":
            return lambda i: (step(i), _timed(s.prepare_next))[1]
        if ahead:
            return lambda i: (s.prepare_next(), _timed(lambda: step(i)))[1]
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
    out["session step, scored ahead"] = _median_ms(session(ahead=True), calls, timed=True)
    out["prepare_next"] = _median_ms(session(timed="prepare"), calls, timed=True)
    fixed = {g: 1 / 8 for g in GOAL_IDS[:8]}
    out["act, a fixed 8-goal blend"] = _median_ms(lambda i: act(fixed, i), calls)
    out["session step, top-8 blend"] = _median_ms(session(mass=0.99, most=8), calls)
    seen = [{g: 1 / len(s) for g in s} for s in sorted(sets)]
    out[f"act, top-8 sets of that session ({len(seen)} distinct)"] = _median_ms(
        lambda i: act(seen[i % len(seen)], i), calls
    )
    out |= _rest_in_process(engine, obs_TD, actions_TP, calls)
    return out


def _rest_in_process(
    engine: object, obs_TD: np.ndarray, actions_TP: np.ndarray, calls: int
) -> dict[str, float]:
    """The REST rows of the module docstring: `session_scene`'s bodies, through the ASGI app."""
    import asyncio
    import json

    from fastapi import FastAPI
    from session_scene import act_bodies, step_bodies

    from services.rest import install_error_handlers, router, sessions_router

    app = FastAPI()
    app.include_router(router)
    app.include_router(sessions_router)
    install_error_handlers(app)
    app.state.engine = engine
    loop = asyncio.new_event_loop()

    def post(path: str, body: bytes) -> bytes:
        """One request through the ASGI app; the answer's body (SystemExit unless 200/201)."""
        scope = {
            "type": "http",
            "asgi": {"version": "3.0"},
            "http_version": "1.1",
            "method": "POST",
            "scheme": "http",
            "path": path,
            "raw_path": path.encode(),
            "query_string": b"",
            "root_path": "",
            "client": ("127.0.0.1", 1),
            "server": ("127.0.0.1", 80),
            "headers": [
                (b"host", b"bench"),
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
            ],
        }
        messages = [{"type": "http.request", "body": body, "more_body": False}]
        sent: list[dict[str, Any]] = []

        async def receive() -> dict[str, Any]:
            return messages.pop() if messages else {"type": "http.disconnect"}

        async def send(message: MutableMapping[str, Any]) -> None:
            sent.append(dict(message))

        loop.run_until_complete(app(scope, receive, send))
        answer = b"".join(m.get("body", b"") for m in sent[1:])
        if sent[0]["status"] not in (200, 201):
            raise SystemExit(f"{path}: status {sent[0]['status']}: {answer!r}")
        return answer

    steps = len(obs_TD)
    acts, bodies = act_bodies(obs_TD, ("b3",)), step_bodies(obs_TD, actions_TP, observed=True)
    out = {"REST act, in-process": _median_ms(lambda i: post("/v1/act", acts[i % steps]), calls)}
    created = post(
        "/v1/sessions",
        json.dumps(
            {"env": "particle", "ego_goal": "a2", "partners": [{"index": 1, "infer": True}]}
        ).encode(),
    )
    path = f"/v1/sessions/{json.loads(created)['session_id']}/steps"
    post(path, step_bodies(obs_TD[:1], actions_TP[:1], observed=False)[0])  # step 0
    out["REST step, in-process"] = _median_ms(
        lambda i: post(path, bodies[i % (steps - 1) + 1]), calls
    )
    loop.close()
    return out


def main() -> None:
    from session_scene import episode

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--store", required=True, help="a store with every particle network")
    parser.add_argument("--calls", type=int, default=1000)
    parser.add_argument(
        "--belief-noise", type=float, default=None, help="belief.noise (η) of the Session rows"
    )
    args = parser.parse_args()
    obs_TD, actions_TP = episode(2, 200)
    for name, ms in breakdown(
        args.store, obs_TD, actions_TP, args.calls, args.belief_noise
    ).items():
        print(f"| {name} | {ms:.3f} |")


if __name__ == "__main__":
    main()
