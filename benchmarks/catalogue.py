"""How a session step's cost grows with the goal catalogue: a step with 4 inferred partners on
the particle world's 35 goals, and on a synthetic catalogue of 350 goals (the 35 and nine
renamed copies of each, every one with its own task and impact network of the trainer's size,
random weights: no training), in-process on the in-memory session store.

Run: `OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/catalogue.py [--goals 35,350]
[--steps 200] [--rounds 3] [--prune 0,0.01] [--prune-error 0.05] [--floor-mass 0.035]
[--actions random|policy]`

Each step's partners' goal beliefs take the evidence of every goal's task network (AAIL's
goal inference, eq. 3-4: one Boltzmann likelihood per goal and partner), so that part grows
with the catalogue; the ego's own networks and the blend do not. Figures: the median over
rounds of each round's p50 and p99 step time in ms, and this process's CPU per step (the step
and `prepare_next`, which scores the next step's evidence ahead, as the servers run it).

Goal pruning (`--prune`, τ values; 0 = off; `belief.prune_below`, δ = `--prune-error`): the
likelihood pass and the blend skip goals below τ while the step's error bound is at most δ.
`--floor-mass M` sets the belief's floor to M / G (the default floor, 0.001, is 0.035 of the
mass at 35 goals and 0.35 at 350, which no bound below δ can prune). For a pruned run the
table adds the share of belief updates that skipped goals (the others had every goal active,
or their bound above δ and every goal scored) and its error against an unpruned session stepped alongside (untimed):
the largest total-variation distance of a belief and of the act's action distribution over
the episode (the latter with the paper's AAIL, which blends at every step; AAIL-B, the
default, blends only where the ego's goal is reached). `--actions policy`: each partner takes the action its own goal's task policy
prefers (partner p the catalogue's goal 7p), so the belief concentrates as it would on a real
partner; `random` (default): uniformly random actions.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from dataclasses import replace
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
from policy.belief import BeliefConfig  # noqa: E402
from services.engine import InferenceEngine  # noqa: E402
from services.sessions import (  # noqa: E402
    Observed,
    Session,
    SessionPartner,
    SessionSettings,
    SessionStore,
)

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


def weights(spec: dict, seed: int) -> bytes:
    """Random weights whose policies differ from goal to goal: qnet_tensors' N(0, 0.1) draws
    give every goal nearly the same uniform policy (a belief that never concentrates, as no
    trained catalogue's would), so the hidden layers are scaled up; the cost is the same."""
    import safetensors.numpy

    from model_store.testing import qnet_tensors

    tensors = qnet_tensors(spec, seed=seed)
    for k, scale in enumerate((8.0, 2.0)):
        tensors[f"layers.{k}.weight"] *= scale
    return safetensors.numpy.save(tensors)


def build_store(url: str, env: str, goals: tuple[str, ...]) -> None:
    from model_store import Lineage, impact_model_name, open_store, task_model_name
    from model_store.testing import qnet_spec
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
                    weights=weights(spec, seed=2 * g + k),
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


def policy_actions(
    engine: InferenceEngine, env: str, goals: tuple[str, ...], obs_TD: np.ndarray
) -> np.ndarray:
    """(T, N_PARTNERS) actions: partner p takes the action goal `goals[7 p]`'s task policy
    rates most likely on its view of o_t."""
    act_TP = np.zeros((len(obs_TD), N_PARTNERS), dtype=np.int64)
    for p in range(N_PARTNERS):
        g = goals.index(goals[(7 * (p + 1)) % len(goals)])
        for t, obs in enumerate(obs_TD):
            scores = [engine.goal_log_likelihoods(env, obs, [p + 1], [a])[0, g] for a in range(5)]
            act_TP[t, p] = int(np.argmax(scores))
    return act_TP


def errors(
    engine: InferenceEngine,
    settings: SessionSettings,
    plain: SessionSettings,
    obs_TD: np.ndarray,
    act_TP: np.ndarray,
) -> tuple[float, float]:
    """The largest total-variation distance over the episode between the beliefs, and the
    action distributions, of a session with `settings` and one with `plain`."""
    # the paper's AAIL blends at every step (AAIL-B only where the ego's goal is reached)
    sessions = [Session(engine, replace(s, method="aail")) for s in (settings, plain)]
    belief_tv = action_tv = 0.0
    for t, obs in enumerate(obs_TD):
        observed = [] if t == 0 else [Observed(j + 1, int(a)) for j, a in enumerate(act_TP[t - 1])]
        answers = [s.step(obs.tolist(), observed) for s in sessions]
        for s in sessions:
            s.prepare_next()
        b = [np.exp(s.export_state().log_belief_PG) for s in sessions]
        belief_tv = max(belief_tv, float(0.5 * np.abs(b[0] - b[1]).sum(axis=1).max()))
        probs = [np.asarray(a.result.probs) for a in answers]
        action_tv = max(action_tv, float(0.5 * np.abs(probs[0] - probs[1]).sum()))
    return belief_tv, action_tv


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--goals", default="35,350", help="catalogue sizes, comma-separated")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--prune", default="0", help="τ values, comma-separated (0: off)")
    parser.add_argument("--prune-error", type=float, default=0.05, help="δ of a pruned run")
    parser.add_argument("--floor-mass", type=float, default=None, help="floor = this / G")
    parser.add_argument("--actions", choices=("random", "policy"), default="random")
    args = parser.parse_args()

    obs_TD, random_TP = episode(N_PARTNERS + 1, args.steps, seed=3)
    taus = [float(x) for x in args.prune.split(",")]
    print(
        f"{args.steps} steps, {N_PARTNERS} inferred partners, {args.rounds} rounds, "
        f"{args.actions} actions, floor mass {args.floor_mass}, δ {args.prune_error}"
    )
    print(
        "\n| goals | τ | step p50 ms | step p99 ms | CPU ms/step | rows pruned | "
        "belief TV max | aail action TV max |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for n_goals in (int(n) for n in args.goals.split(",")):
        env = register_catalogue(n_goals)
        with tempfile.TemporaryDirectory() as tmp:
            url = f"sqlite:///{Path(tmp) / 'models.db'}"
            build_store(url, env, catalogue(n_goals))
            with SqlModelStore(url) as model_store:
                engine = InferenceEngine(model_store)
                store = SessionStore(engine)
                act_TP = random_TP
                if args.actions == "policy":
                    act_TP = policy_actions(engine, env, catalogue(n_goals), obs_TD)
                floor = {} if args.floor_mass is None else {"floor": args.floor_mass / n_goals}
                partners = tuple(SessionPartner(i + 1, infer=True) for i in range(N_PARTNERS))
                plain = SessionSettings(env, "a2", partners, seed=7, belief=BeliefConfig(**floor))
                for tau in taus:
                    belief = BeliefConfig(**floor, prune_below=tau, prune_error=args.prune_error)
                    settings = SessionSettings(env, "a2", partners, seed=7, belief=belief)
                    run(store, settings, obs_TD[:20], act_TP)  # warm-up: load, stack, compile
                    p50, p99, cpu = [], [], []
                    before = engine.stats.snapshot()
                    for _ in range(args.rounds):
                        times, cpu_s = run(store, settings, obs_TD, act_TP)
                        p50.append(float(np.percentile(times, 50)) * 1e3)
                        p99.append(float(np.percentile(times, 99)) * 1e3)
                        cpu.append(cpu_s * 1e3)
                    after = engine.stats
                    pruned = after.pruned_updates - before.pruned_updates
                    updates = args.rounds * (len(obs_TD) - 1) * N_PARTNERS
                    share, belief_tv, action_tv = "-", "-", "-"
                    if tau > 0:
                        share = f"{pruned / updates:.2f}"
                        b_tv, a_tv = errors(engine, settings, plain, obs_TD, act_TP)
                        belief_tv, action_tv = f"{b_tv:.2g}", f"{a_tv:.2g}"
                    print(
                        f"| {n_goals} | {tau:g} | {statistics.median(p50):.3f} | "
                        f"{statistics.median(p99):.3f} | {statistics.median(cpu):.3f} | "
                        f"{share} | {belief_tv} | {action_tv} |",
                        flush=True,
                    )


if __name__ == "__main__":
    main()
