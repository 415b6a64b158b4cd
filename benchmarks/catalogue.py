"""How a session step's cost grows with the goal catalogue: a step with 4 inferred partners on
the particle world's 35 goals, and on a synthetic catalogue of 350 goals (the 35 and nine
renamed copies of each, every one with its own task and impact network of the trainer's size,
random weights: no training), in-process on the in-memory session store.

Run: `OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/catalogue.py [--goals 35,350]
[--steps 200] [--rounds 3]`

Each step's partners' goal beliefs take the evidence of every goal's task network (AAIL's
goal inference, eq. 3-4: one Boltzmann likelihood per goal and partner), so that part grows
with the catalogue; the ego's own networks and the blend do not. Figures: the median over
rounds of each round's p50 and p99 step time in ms, and this process's CPU per step (the step
and `prepare_next`, which scores the next step's evidence ahead, as the servers run it).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from session_scene import episode  # noqa: E402

from envs.particle.domain import ParticleDomain  # noqa: E402
from envs.particle.env import ParticleCoexistenceEnv  # noqa: E402
from envs.particle.goals import GOAL_IDS  # noqa: E402
from envs.registry import EnvPlugin, register_env  # noqa: E402
from model_store.sql import SqlModelStore  # noqa: E402
from services.engine import InferenceEngine  # noqa: E402
from services.sessions import Observed, SessionPartner, SessionSettings, SessionStore  # noqa: E402

N_PARTNERS = 4


def catalogue(n_goals: int) -> tuple[str, ...]:
    """The particle goals first (the ego's target boxes are theirs), then renamed copies."""
    copies = (f"{goal}.{k}" for k in range(1, n_goals) for goal in GOAL_IDS)
    return (GOAL_IDS + tuple(copies))[:n_goals]


def register_catalogue(n_goals: int) -> str:
    """A particle world whose goal catalogue has `n_goals` goals, registered in this process;
    returns its name."""
    name = f"particle-g{n_goals}"
    domain = type(
        "CatalogueDomain", (ParticleDomain,), {"name": name, "goals": catalogue(n_goals)}
    )()
    register_env(EnvPlugin(domain=domain, make_env=ParticleCoexistenceEnv), replace=True)
    return name


def build_store(url: str, env: str, goals: tuple[str, ...]) -> None:
    from model_store import Lineage, impact_model_name, open_store, task_model_name
    from model_store.testing import qnet_spec, qnet_weights
    from trainer.config import TaskConfig

    spec = qnet_spec(obs_dim=8, n_actions=5, hidden=TaskConfig().hidden)
    with open_store(url, create=True) as store:
        for g, goal in enumerate(goals):
            for k, (kind, name) in enumerate(
                (("task", task_model_name(env, goal)), ("impact", impact_model_name(env, goal)))
            ):
                store.create_model(
                    name, env=env, kind=kind, goals=[goal], obs_dim=8, n_actions=5, exist_ok=True
                )
                store.register_version(
                    name,
                    spec=spec,
                    weights=qnet_weights(spec, seed=2 * g + k),
                    lineage=Lineage(config={"alpha": 0.02}, seed=2 * g + k),
                    aliases=("production",),
                )


def run(
    store: SessionStore, settings: SessionSettings, obs_TD: np.ndarray, act_TP: np.ndarray
) -> tuple[list[float], float]:
    """Seconds per step (step 0, with no evidence, left out) and CPU seconds per step."""
    cpu = time.process_time()
    session_id = store.create(settings).session_id
    times = []
    for t, obs in enumerate(obs_TD):
        observed = [] if t == 0 else [Observed(j + 1, int(a)) for j, a in enumerate(act_TP[t - 1])]
        started = time.perf_counter()
        store.step(session_id, obs.tolist(), observed, expected_step=t)
        times.append(time.perf_counter() - started)
        store.prepare_next(session_id)
    store.delete(session_id)
    return times[1:], (time.process_time() - cpu) / len(obs_TD)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--goals", default="35,350", help="catalogue sizes, comma-separated")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()

    obs_TD, act_TP = episode(N_PARTNERS + 1, args.steps, seed=3)
    print(f"{args.steps} steps, {N_PARTNERS} inferred partners, {args.rounds} rounds")
    print("\n| goals | step p50 ms | step p99 ms | CPU ms/step |")
    print("|---|---|---|---|")
    for n_goals in (int(n) for n in args.goals.split(",")):
        env = register_catalogue(n_goals)
        with tempfile.TemporaryDirectory() as tmp:
            url = f"sqlite:///{Path(tmp) / 'models.db'}"
            build_store(url, env, catalogue(n_goals))
            with SqlModelStore(url) as model_store:
                store = SessionStore(InferenceEngine(model_store))
                settings = SessionSettings(
                    env,
                    "a2",
                    tuple(SessionPartner(i + 1, infer=True) for i in range(N_PARTNERS)),
                    seed=7,
                )
                run(store, settings, obs_TD[:20], act_TP)  # warm-up: load, stack, compile
                p50, p99, cpu = [], [], []
                for _ in range(args.rounds):
                    times, cpu_s = run(store, settings, obs_TD, act_TP)
                    p50.append(float(np.percentile(times, 50)) * 1e3)
                    p99.append(float(np.percentile(times, 99)) * 1e3)
                    cpu.append(cpu_s * 1e3)
        print(
            f"| {n_goals} | {statistics.median(p50):.3f} | {statistics.median(p99):.3f} | "
            f"{statistics.median(cpu):.3f} |"
        )


if __name__ == "__main__":
    main()
