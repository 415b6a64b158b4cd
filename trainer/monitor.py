"""Goal monitors: per goal, a network that says which actions keep an agent's reached goal, so
that AAIL-B needs no answer from the environment at execution (our addition to the paper).

Why. AAIL-B blends only where the ego's goal is reached (R2) and only among the actions that
keep it (R4), and asks the environment both (`Domain.goal_reached`, `Domain.goal_kept`): the
particle world simulates its dynamics one step and a coast ahead. A robot's environment cannot
answer that at execution, and the ego's task network cannot stand in: its Q-values do not tell
the keeping actions from the rest (`evaluation.partners.task_q_oracle`; the task reward also
holds the partner's distance to the goal's influence area). Without either answer AAIL-B
strands its ego (`reports/partners/draw6262/no_oracle/`).

What. For goal g, a network M_g of the task networks' form (the same pair view in, one output per
action) whose output is the logit of P(after action a the agent is at its goal and can stay:
`Domain.goal_kept`). Trained at training time, where the environment is at hand, by logistic
regression (binary cross-entropy) on states drawn fresh at every step from `states(rng, goal,
n)`, labelled by the domain's `goal_kept` (the answer R4 uses), or by a conservative version of
it where the environment's trainer gives one (`monitor_labels`: the particle world's shrinks the
target area, so that the monitor's errors at the edge fall inside it). At
execution the engine reads K = {a : M_g(s, a) > log 9}, the actions it gives a probability of
at least 0.9 (`policy.regret_bound.MONITOR_KEEP_LOGIT`), as R4's, the goal reached where K is
not empty (R2), and asks the environment nothing (`services.engine.engine.aail_bounded_guard`).

The gate, on `MonitorConfig.holdout` fresh states per goal: of the actions the monitor says
keep the goal, at most `max_false_keeps` may lose it (a false keep lets the blend pull the ego
out of its target), and `misses` (keeping actions it does not call so) is reported, not gated (a
miss only means less help).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace

import numpy as np
import torch
import torch.nn.functional as F

from envs.base import Domain
from model_store.entities import Lineage, ModelVersion
from model_store.lineage import code_version
from model_store.naming import monitor_model_name
from model_store.store import ModelStore
from policy.qnet import QNetSpec, QNetwork, StackedQNet, weights_to_safetensors
from policy.regret_bound import MONITOR_KEEP_LOGIT

GATE_RETRIES = 2  # retrains of the goals whose monitor failed its gate
RETRY_SEED = 7919  # seed offset per retry

# (rng, goal, n) -> n observations of a two-agent scene, the monitored agent first
StateSampler = Callable[[np.random.Generator, str, int], np.ndarray]
# (observations (n, D), goal) -> (n, A) bool: the labels a monitor learns where they are not the
# domain's `goal_kept` itself (a conservative version of it: `trainer.particle.monitor_states`)
Labeller = Callable[[np.ndarray, str], np.ndarray]


@dataclass(frozen=True)
class MonitorConfig:
    steps: int = 6000  # Adam steps, each on fresh states
    states: int = 256  # states per goal per step
    lr: float = 3e-3
    hidden: tuple[int, ...] = (128, 128)
    holdout: int = 4000  # states per goal for the gate
    max_false_keeps: float = 0.03  # the gate: share of the actions called keeping that lose it

    def to_dict(self) -> dict[str, object]:
        return {**asdict(self), "hidden": list(self.hidden)}


@dataclass(frozen=True)
class MonitorGate:
    """One goal's gate on its held-out states."""

    false_keeps: float  # of the actions called keeping, the share that lose the goal
    misses: float  # of the keeping actions, the share not called so
    reached_errors: float  # states whose "reached" (some action keeps) the monitor gets wrong
    passed: bool

    def metrics(self) -> dict[str, object]:
        return asdict(self)


@dataclass(frozen=True)
class TrainedMonitors:
    goals: tuple[str, ...]
    nets: StackedQNet
    gates: tuple[MonitorGate, ...]
    config: MonitorConfig
    seed: int


def _labelled(
    domain: Domain,
    states: StateSampler,
    goals: Sequence[str],
    n: int,
    rng: np.random.Generator,
    labels: Labeller | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """(G, n, view) inputs and (G, n, A) 0/1 labels: n fresh states per goal, labelled by
    `labels` (None: the domain's `goal_kept`)."""
    views, targets = [], []
    for goal in goals:
        obs = states(rng, goal, n)
        kept = domain.goal_kept(obs, 2, goal) if labels is None else labels(obs, goal)
        if kept is None:
            raise ValueError(f"env {domain.name!r}: goal_kept answers None, nothing to learn")
        views.append(domain.task_views(obs, 2)[:, 0])
        targets.append(np.asarray(kept, dtype=np.float32))
    return torch.from_numpy(np.stack(views)).float(), torch.from_numpy(np.stack(targets))


def train_monitors(
    domain: Domain,
    states: StateSampler,
    goals: Sequence[str],
    config: MonitorConfig,
    seed: int,
    progress: Callable[[int, int], None] | None = None,
    labels: Labeller | None = None,
) -> TrainedMonitors:
    """One monitor per goal, trained together as one stacked network on `labels` (None: the
    domain's `goal_kept`), then gated against the domain's `goal_kept`."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    spec = QNetSpec(domain.pair_obs_dim, domain.n_actions, hidden=config.hidden)
    nets = StackedQNet(spec, len(goals), generator=torch.Generator().manual_seed(seed))
    optimiser = torch.optim.Adam(nets.parameters(), lr=config.lr)
    for step in range(config.steps):
        x, y = _labelled(domain, states, goals, config.states, rng, labels)
        loss = F.binary_cross_entropy_with_logits(nets(x), y)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        if progress is not None and (step + 1) % 100 == 0:
            progress(step + 1, config.steps)
    x, y = _labelled(domain, states, goals, config.holdout, np.random.default_rng(seed + 1))
    with torch.no_grad():
        called = (nets(x) > MONITOR_KEEP_LOGIT).numpy()
    truth = y.numpy() > 0.5
    gates = []
    for g in range(len(goals)):
        false_keeps = float((called[g] & ~truth[g]).sum() / max(int(called[g].sum()), 1))
        misses = float((truth[g] & ~called[g]).sum() / max(int(truth[g].sum()), 1))
        reached_errors = float((called[g].any(axis=1) != truth[g].any(axis=1)).mean())
        passed = false_keeps <= config.max_false_keeps
        gates.append(MonitorGate(false_keeps, misses, reached_errors, passed))
    return TrainedMonitors(tuple(goals), nets, tuple(gates), config, seed)


def train_gated(
    domain: Domain,
    states: StateSampler,
    goals: Sequence[str],
    config: MonitorConfig,
    seed: int,
    progress: Callable[[str, int], Callable[[int, int], None]] | None = None,
    labels: Labeller | None = None,
) -> list[TrainedMonitors]:
    """`train_monitors` of `goals`, then of the goals whose gate failed again, with twice the
    steps and a fresh seed, up to `GATE_RETRIES` times (as the zoo's networks are retried);
    every attempt's monitors, to be published in order. `progress(description, total)` gives
    each attempt's progress callback."""
    attempts: list[TrainedMonitors] = []
    todo, steps = list(goals), config.steps
    for attempt in range(GATE_RETRIES + 1):
        run = replace(config, steps=steps)
        label = f"monitor {todo[0]}..{todo[-1]}" + (f" (retry {attempt})" if attempt else "")
        advance = None if progress is None else progress(label, run.steps)
        trained = train_monitors(
            domain, states, todo, run, seed + RETRY_SEED * attempt, advance, labels
        )
        attempts.append(trained)
        todo = [g for g, gate in zip(trained.goals, trained.gates, strict=True) if not gate.passed]
        if not todo:
            break
        steps *= 2
    return attempts


def publish_monitors(
    store: ModelStore, trained: TrainedMonitors, *, env: str, alias: str = "production"
) -> list[ModelVersion]:
    """Register `{env}/monitor/{goal}` for every goal; `alias` only where its gate passed."""
    versions = []
    spec = trained.nets.spec
    config = {**trained.config.to_dict(), "kind": "monitor"}
    for g, goal in enumerate(trained.goals):
        name = monitor_model_name(env, goal)
        store.create_model(
            name,
            env=env,
            kind="monitor",
            goals=(goal,),
            obs_dim=spec.obs_dim,
            n_actions=spec.n_actions,
            description=f"Goal monitor: which actions keep goal {goal} once reached (AAIL-B).",
            exist_ok=True,
        )
        net = QNetwork(spec)
        net.load_state_dict(trained.nets.member_state(g))
        gate = trained.gates[g]
        lineage = Lineage(
            config=config,
            seed=trained.seed,
            code_version=code_version(),
            metrics={"gate": gate.metrics()},
            parents=(),
            registered_by="coexist-trainer",
        )
        versions.append(
            store.register_version(
                name,
                spec=spec.to_json(),
                weights=weights_to_safetensors(net),
                lineage=lineage,
                aliases=("latest", alias) if gate.passed else ("latest",),
            )
        )
        verdict = "passed" if gate.passed else "failed"
        store.update_model(name, tags={"gate": verdict, "seed": str(trained.seed)})
    return versions
