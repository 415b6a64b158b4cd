"""Online goal inference, part 1: does the belief find a partner's goal?

    result = run_accuracy(engine, AccuracyConfig())   # belief after k observed actions, k = 0..50
    result.summary()                                  # accuracy, top-3, cross-entropy per k

Seeded two-agent particle episodes. The partner (agent 1) samples its actions from the Boltzmann
policy softmax(Q/α) of its true goal's task network, taken from a *separately trained* population
(`partner_alias`, default `partners`, as in the paper suite): the likelihood networks (`alias`,
default `production`) did not generate the behaviour they score. The ego (agent 0) acts with AAIL
through the engine, its partner given as `goal_probs` = the belief's blend distribution, exactly
as a session step does. After every step the partner's action is scored by all 35 task networks
(`InferenceEngine.goal_log_likelihoods`, one batched pass) and the belief updated
(`policy.belief.update_log_belief`): the server's own two calls, in the server's order.

k counts the partner actions incorporated: b_0 is the prior (uniform), b_k the belief after the
k-th update; its top goal at k = 0 is the first goal of the catalogue (ties go by goal order),
right for 1 episode in 35.

Several belief settings (`beliefs`: forgetting λ, floor ε, likelihood temperature α and noise
η) are tracked on the *same* trajectories (the first one drives the ego), so their curves differ
by the belief maths alone; one likelihood pass per distinct α, each η mixed into it by
`policy.belief.mix_uniform_noise` (what the engine does with `noise`). `switch_at` makes the partner change its mind at
that step (its goal moves to another, seeded, goal), to show what forgetting and the floor buy.

Goals can be indistinguishable by behaviour: a partner at rest in cell `d4` acts as the goals
`d4`, `d` (its column) and `4` (its row) all would. *Nested* accuracy counts the top goal right
when it is the true goal or its target area contains, or lies inside, the true one.

| array          | shape        | meaning                                              |
|----------------|--------------|------------------------------------------------------|
| `top1_CEK`     | (C, E, K+1)  | top goal of b_k is the partner's current goal        |
| `top3_CEK`     | (C, E, K+1)  | the current goal is among the three most likely      |
| `nested_CEK`   | (C, E, K+1)  | the top goal is the current goal up to nesting       |
| `xent_CEK`     | (C, E, K+1)  | cross-entropy -log b_k(g*) in nats                   |
| `goals_EK`     | (E, K+1)     | index of the partner's current goal at each k        |
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from envs.particle.batched import BatchedParticleWorld
from envs.particle.goals import GOAL_IDS, N_GOALS, TARGET_BOXES_G4
from envs.particle.scenarios import start_states
from evaluation.partner_types import partner_probs as partner_type_probs
from evaluation.partner_types import partner_type
from policy.belief import (
    BeliefConfig,
    belief_cross_entropy,
    blend_goal_probs,
    initial_log_belief,
    mix_uniform_noise,
    prior_log_probs,
    update_log_belief,
)
from policy.sampling import sample_actions
from services.engine import ActRequest, InferenceEngine, PartnerSpec
from services.engine.environments import env_runtime
from services.sessions.messages import SessionSettings

ProgressFn = Callable[[int, int], None]  # (step, total steps)
# how a session blends impact networks by the belief, by default (the runs use the same)
_SESSION_DEFAULTS: dict[str, Any] = {f.name: f.default for f in fields(SessionSettings)}
SESSION_BLEND_MASS: float = _SESSION_DEFAULTS["blend_mass"]
SESSION_BLEND_MAX_GOALS: int | None = _SESSION_DEFAULTS["blend_max_goals"]
DEFAULT_BELIEFS = (BeliefConfig(), BeliefConfig(forgetting=1.0))


def belief_label(config: BeliefConfig) -> str:
    """ "λ = 0.95, ε = 0.001" (and the likelihood's α when it is not the engine's default, its
    noise η when there is some)."""
    label = f"λ = {config.forgetting:g}, ε = {config.floor:g}"
    if config.temperature is not None:
        label += f", α = {config.temperature:g}"
    return label if config.noise == 0 else f"{label}, η = {config.noise:g}"


def _nested_targets() -> np.ndarray:
    """(G, G): goal g's target area contains goal h's or lies inside it (g = h included)."""
    b = TARGET_BOXES_G4
    inside = (
        (b[:, None, 0] <= b[None, :, 0] + 1e-9)
        & (b[:, None, 1] >= b[None, :, 1] - 1e-9)
        & (b[:, None, 2] <= b[None, :, 2] + 1e-9)
        & (b[:, None, 3] >= b[None, :, 3] - 1e-9)
    )
    return inside | inside.T


NESTED_GG = _nested_targets()


@dataclass(frozen=True)
class AccuracyConfig:
    """Settings of the accuracy experiment (module docstring)."""

    episodes_per_goal: int = 6  # 35 true goals × 6 = 210 episodes
    k_max: int = 50
    seed: int = 0
    beliefs: tuple[BeliefConfig, ...] = DEFAULT_BELIEFS  # the first drives the ego
    blend_mass: float = SESSION_BLEND_MASS  # the ego's blend of impact networks by the belief
    blend_max_goals: int | None = SESSION_BLEND_MAX_GOALS
    switch_at: int | None = None  # the partner's goal changes after this many steps
    alias: str = "production"
    partner_alias: str = "partners"
    env: str = "particle"
    # how the partner acts (`evaluation.partner_types`; its goal switches only by `switch_at`)
    partner_type: str = "other_seed"

    def __post_init__(self) -> None:
        if self.episodes_per_goal < 1:
            raise ValueError(f"episodes_per_goal: expected >= 1, got {self.episodes_per_goal}")
        if self.k_max < 1:
            raise ValueError(f"k_max: expected >= 1, got {self.k_max}")
        if not self.beliefs:
            raise ValueError("beliefs: expected at least one belief setting")
        if self.switch_at is not None and not 0 < self.switch_at < self.k_max:
            raise ValueError(f"switch_at: expected 1..{self.k_max - 1}, got {self.switch_at}")
        for config in self.beliefs:
            config.validate(N_GOALS)
        if partner_type(self.partner_type).switches:
            raise ValueError("partner_type: a goal switch is set by switch_at here")

    @property
    def episodes(self) -> int:
        return self.episodes_per_goal * N_GOALS


def wilson_interval(
    successes: np.ndarray, n: int, z: float = 1.96
) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval of a binomial proportion (95 % for z = 1.96), elementwise; unlike
    the normal approximation it stays inside [0, 1] and is not empty at 0 or n successes."""
    if n < 1:
        raise ValueError(f"n: expected >= 1, got {n}")
    p = np.asarray(successes, dtype=np.float64) / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


@dataclass
class AccuracyResult:
    config: AccuracyConfig
    top1_CEK: np.ndarray
    top3_CEK: np.ndarray
    nested_CEK: np.ndarray
    xent_CEK: np.ndarray
    goals_EK: np.ndarray
    ego_goals_E: np.ndarray
    wall_s: float = 0.0
    # the first episode's record, for the tests' independent recomputation of the belief
    trace_obs_KD: np.ndarray = field(default_factory=lambda: np.zeros((0, 8)))
    trace_actions_K: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    final_log_belief_CEG: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, N_GOALS)))
    top_EK: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=np.int64))  # driver's

    def summary(self) -> dict[str, dict[str, list[float]]]:
        """Per belief setting (`belief_label`): per-k accuracy (Wilson 95 % band), top-3 and
        nested accuracy, mean cross-entropy ± SE; the JSON the report and the plots read."""
        n = self.top1_CEK.shape[1]
        out: dict[str, dict[str, list[float]]] = {}
        for c, belief in enumerate(self.config.beliefs):
            hits = self.top1_CEK[c].sum(axis=0)
            lo, hi = wilson_interval(hits, n)
            xent = self.xent_CEK[c]
            out[belief_label(belief)] = {
                "accuracy": (hits / n).round(4).tolist(),
                "accuracy_lo": lo.round(4).tolist(),
                "accuracy_hi": hi.round(4).tolist(),
                "top3": self.top3_CEK[c].mean(axis=0).round(4).tolist(),
                "nested": self.nested_CEK[c].mean(axis=0).round(4).tolist(),
                "cross_entropy": xent.mean(axis=0).round(4).tolist(),
                "cross_entropy_se": (xent.std(axis=0, ddof=1) / math.sqrt(n)).round(4).tolist()
                if n > 1
                else [0.0] * xent.shape[1],
            }
        return out

    def confusions(self, k: int, limit: int = 8) -> list[tuple[str, str, int]]:
        """(true goal, top goal, episodes) of the most frequent errors of the driving belief
        at k: which goals the partner's behaviour does not tell apart."""
        counts: dict[tuple[str, str], int] = {}
        for e in range(self.top1_CEK.shape[1]):
            if not self.top1_CEK[0, e, k]:
                true = GOAL_IDS[int(self.goals_EK[e, k])]
                top = GOAL_IDS[int(self.top_EK[e, k])]
                counts[(true, top)] = counts.get((true, top), 0) + 1
        ranked = sorted(counts.items(), key=lambda item: (-item[1], item[0]))
        return [(t, g, n) for (t, g), n in ranked[:limit]]


def _top_index(log_belief_G: np.ndarray) -> int:
    return int(np.argmax(log_belief_G))  # the first maximum: ties by goal order (top_goals)


def _in_top3(log_belief_G: np.ndarray, goal: int) -> bool:
    # stable sort: equal probabilities keep the catalogue order, as `top_goals` does
    order = np.argsort(-log_belief_G, kind="stable")
    return bool(goal in order[:3])


def partner_probs(
    engine: InferenceEngine,
    env: str,
    obs_BD: np.ndarray,
    goals_B: np.ndarray,
    alias: str,
) -> np.ndarray:
    """Each row's partner policy softmax(Q/α) of its goal's task network (`sl` through the
    engine at the network's training α), one engine call per distinct goal; (B, A)."""
    parts = []
    for goal in np.unique(goals_B):
        rows = np.flatnonzero(goals_B == goal)
        request = ActRequest(env, GOAL_IDS[int(goal)], obs_BD[rows], method="sl", alias=alias)
        parts.append((rows, np.asarray([r.probs for r in engine.act(request)], dtype=np.float64)))
    probs_BA = np.zeros((obs_BD.shape[0], parts[0][1].shape[1]), dtype=np.float64)
    for rows, probs in parts:
        probs_BA[rows] = probs
    return probs_BA


def _partner_probs(
    engine: InferenceEngine,
    cfg: AccuracyConfig,
    obs_BD: np.ndarray,
    state_BN4: np.ndarray,
    goals_B: np.ndarray,
) -> np.ndarray:
    """The partners' action distributions as `cfg.partner_type` acts, (B, A): its networks'
    (`partner_probs`), or the type's own rule, one call per distinct goal."""
    kind = partner_type(cfg.partner_type)
    if kind.name == "other_seed" and cfg.partner_alias:  # the suite's historical path
        return partner_probs(engine, cfg.env, obs_BD, goals_B, cfg.partner_alias)
    alias = kind.alias(cfg.alias, cfg.partner_alias)

    def act(request: ActRequest) -> np.ndarray:
        return engine.act_columns(request).probs

    probs_BA = np.zeros((obs_BD.shape[0], engine_actions(cfg.env)))
    for goal in np.unique(goals_B).tolist():
        rows = np.flatnonzero(goals_B == goal)
        probs_BA[rows] = partner_type_probs(
            kind,
            alias,
            act,
            GOAL_IDS[goal],
            obs_BD[rows],
            state_BN4[rows],
            np.ones(rows.size, dtype=np.int64),
            probs_BA.shape[1],
            cfg.env,
        )
    return probs_BA


def engine_actions(env: str) -> int:
    return env_runtime(env).domain.n_actions


def ego_probs_with_belief(
    engine: InferenceEngine,
    env: str,
    ego_goal: str,
    obs_D: np.ndarray,
    log_belief_G: np.ndarray,
    *,
    alias: str,
    mass: float = SESSION_BLEND_MASS,
    max_goals: int | None = SESSION_BLEND_MAX_GOALS,
    goals: Sequence[str] = GOAL_IDS,
) -> np.ndarray:
    """The ego's AAIL distribution with its partner (index 1) given by the belief's blend
    distribution (`mass`, `max_goals`: a session's `blend_mass`, `blend_max_goals`): what a
    session step acts with after its belief update; (A,)."""
    goal_probs = blend_goal_probs(log_belief_G, goals, mass, max_goals)
    request = ActRequest(
        env, ego_goal, obs_D[None], (PartnerSpec(1, goal_probs=goal_probs),), alias=alias
    )
    return np.asarray(engine.act(request)[0].probs, dtype=np.float64)


def run_accuracy(
    engine: InferenceEngine, config: AccuracyConfig, *, progress: ProgressFn | None = None
) -> AccuracyResult:
    """The experiment of the module docstring; every episode runs `k_max` steps (an episode
    whose agents are all inside their targets goes on: the partner keeps acting)."""
    started = time.perf_counter()
    cfg, n_eps, k_max = config, config.episodes, config.k_max
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, 9]))
    goals_E = np.arange(n_eps) % N_GOALS  # every goal the partner's true goal equally often
    ego_goals_E = rng.integers(0, N_GOALS, n_eps)
    goals_EK = np.repeat(goals_E[:, None], k_max + 1, axis=1)
    if cfg.switch_at is not None:  # a new goal, never the old one
        shifted = (goals_E + rng.integers(1, N_GOALS, n_eps)) % N_GOALS
        goals_EK[:, cfg.switch_at :] = shifted[:, None]
    u_KE2 = rng.random((k_max, n_eps, 2))
    world = BatchedParticleWorld(np.stack([ego_goals_E, goals_E], axis=1), max_steps=k_max + 1)
    obs_END = world.reset(start_states(1000 * cfg.seed + 50, n_eps, 2))

    configs = cfg.beliefs
    temperatures = list(dict.fromkeys(b.temperature for b in configs))  # one pass each
    n_actions = engine_actions(cfg.env)
    log_prior_G = prior_log_probs(GOAL_IDS)
    belief_CEG = np.stack(
        [np.tile(initial_log_belief(log_prior_G, b), (n_eps, 1)) for b in configs]
    )
    shape = (len(configs), n_eps, k_max + 1)
    top1, top3, nested = np.zeros(shape, bool), np.zeros(shape, bool), np.zeros(shape, bool)
    xent = np.zeros(shape)
    top_EK = np.zeros((n_eps, k_max + 1), dtype=np.int64)
    trace_obs, trace_actions = [], []

    def record(k: int) -> None:
        for c in range(len(configs)):
            for e in range(n_eps):
                goal = int(goals_EK[e, k])
                top = _top_index(belief_CEG[c, e])
                top1[c, e, k] = top == goal
                nested[c, e, k] = NESTED_GG[top, goal]
                top3[c, e, k] = _in_top3(belief_CEG[c, e], goal)
                xent[c, e, k] = belief_cross_entropy(belief_CEG[c, e], goal)
                if c == 0:
                    top_EK[e, k] = top

    record(0)
    for t in range(k_max):
        if progress is not None:
            progress(t, k_max)
        if cfg.switch_at is not None and t == cfg.switch_at:
            world.set_goals(np.stack([ego_goals_E, goals_EK[:, t]], axis=1))
        actions_E2 = np.zeros((n_eps, 2), dtype=np.int64)
        p_probs = _partner_probs(engine, cfg, obs_END[:, 1], world.state, goals_EK[:, t])
        actions_E2[:, 1] = sample_actions(p_probs, u_KE2[t, :, 1])
        for e in range(n_eps):
            probs = ego_probs_with_belief(
                engine,
                cfg.env,
                GOAL_IDS[ego_goals_E[e]],
                obs_END[e, 0],
                belief_CEG[0, e],
                alias=cfg.alias,
                mass=cfg.blend_mass,
                max_goals=cfg.blend_max_goals,
            )
            actions_E2[e, 0] = sample_actions(probs[None], u_KE2[t, e : e + 1, 0])[0]
            # the partner acted on the observation the ego had at t: score it there
            log_lik = {
                alpha: engine.goal_log_likelihoods(
                    cfg.env,
                    obs_END[e, 0],
                    [1],
                    [int(actions_E2[e, 1])],
                    alias=cfg.alias,
                    temperature=alpha,
                )
                for alpha in temperatures
            }
            for c, belief in enumerate(configs):
                lik = mix_uniform_noise(log_lik[belief.temperature], belief.noise, n_actions)
                updated = update_log_belief(belief_CEG[c, e][None], lik, log_prior_G[None], belief)
                belief_CEG[c, e] = updated[0]
        trace_obs.append(obs_END[0, 0].copy())
        trace_actions.append(int(actions_E2[0, 1]))
        obs_END = world.step(actions_E2).next_obs_BND
        record(t + 1)
    return AccuracyResult(
        config=cfg,
        top1_CEK=top1,
        top3_CEK=top3,
        nested_CEK=nested,
        xent_CEK=xent,
        goals_EK=goals_EK,
        ego_goals_E=ego_goals_E,
        wall_s=time.perf_counter() - started,
        trace_obs_KD=np.stack(trace_obs),
        trace_actions_K=np.asarray(trace_actions, dtype=np.int64),
        final_log_belief_CEG=belief_CEG.copy(),
        top_EK=top_EK,
    )
