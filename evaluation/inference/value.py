"""Online goal inference, part 2: what inferring a partner's goal is worth.

    value = run_value(engine, ValueConfig())      # SL, AAIL announced, AAIL inferred, paired
    value.scenarios["non_aligned"].comparison      # returns, tests, recovered fraction

The paper suite's two-agent scenarios (`aligned`: ego `c`, partner `c4`; `non_aligned`: ego `a2`,
partner `b3`) and its sample of goal pairs (`evaluation.config`, the same start seeds, so SL and
AAIL-announced are the paper suite's own episodes for the same networks), under three egos:

| method           | the ego's partner                                                    |
|------------------|----------------------------------------------------------------------|
| `sl`             | ignored (the task policy alone)                                      |
| `aail`           | announced: its true goal (`evaluation.rollout.run_cells`)            |
| `aail-inferred`  | a belief from its observed actions, uniform prior, the server's      |
|                  | default `BeliefConfig`; AAIL blends impact networks by the belief    |

The inferred ego runs the steps of a session: before acting on o_t it updates the belief with
the partner's action a_{t-1} scored on o_{t-1} (`goal_log_likelihoods`), then acts with
`goal_probs = blend_goal_probs(belief)`. Partners act as in the paper suite (their own task
policy, `partner_alias` population). Paired: all three methods face the same start states and
the same uniforms u[t, e, i] (`evaluation.rollout.uniforms`).

*Recovered*: the share of the announced-goal gain that inference keeps,
(inferred − SL) / (announced − SL), on the team return; a 95 % percentile bootstrap over the
paired units (episodes of a scenario, or pairs of a pair group) gives its interval. Where the
announced − SL gap is not significant the ratio means little (its interval says so).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from envs.particle.batched import BatchedParticleWorld
from envs.particle.goals import GOAL_IDS, goal_indices
from envs.particle.scenarios import sample_goal_pairs, start_states
from evaluation.backend import EngineBackend
from evaluation.config import Scenario, SuiteConfig, paper_scenarios
from evaluation.inference.accuracy import (
    SESSION_BLEND_MASS,
    SESSION_BLEND_MAX_GOALS,
    ego_probs_with_belief,
    partner_probs,
)
from evaluation.paper.pairs import units_of
from evaluation.rollout import (
    Cell,
    CellResult,
    EpisodeTally,
    run_cells,
    uniforms,
)
from evaluation.stats import MeanSE, mean_se, paired_diff, wilcoxon_p
from policy.belief import BeliefConfig, initial_log_belief, prior_log_probs, update_log_belief
from policy.sampling import sample_actions
from services.engine import InferenceEngine

INFERRED = "aail-inferred"
VALUE_METHODS = ("sl", "aail", INFERRED)
MEASURES = ("team", "ego", "others")
ProgressFn = Callable[[str, int, int], None]  # (label, step, active episodes)


@dataclass(frozen=True)
class ValueConfig:
    episodes: int = 200
    pairs: int = 100
    pair_episodes: int = 20
    max_steps: int = 400
    seed: int = 0
    belief: BeliefConfig = field(default_factory=BeliefConfig)
    blend_mass: float = SESSION_BLEND_MASS  # as a session blends impact nets by the belief
    blend_max_goals: int | None = SESSION_BLEND_MAX_GOALS
    bootstrap: int = 2000
    alias: str = "production"
    partner_alias: str = "partners"
    env: str = "particle"

    def suite_config(self) -> SuiteConfig:
        """The paper suite's settings these scenarios come from (same start seeds)."""
        return SuiteConfig(
            episodes=self.episodes,
            pair_episodes=self.pair_episodes,
            max_steps=self.max_steps,
            seed=self.seed,
            alias=self.alias,
            partner_alias=self.partner_alias,
        )


def value_scenarios(config: ValueConfig) -> tuple[list[Scenario], list[Scenario]]:
    """The paper suite's aligned and non-aligned scenarios, and `pairs` goal pairs drawn from
    the whole 35 × 35 catalogue (start seeds 1000 seed + 100 + i; the analysis keeps the
    strictly aligned and strictly non-aligned ones, `envs.particle.scenarios.pair_class`)."""
    suite = config.suite_config()
    named = [s for s in paper_scenarios(suite) if s.n_agents == 2]
    if config.pairs == 0:
        return named, []
    base = 1000 * config.seed
    drawn = sample_goal_pairs(base + 7, config.pairs)
    pairs = [
        Scenario(f"pair:{ego}+{partner}", ego, (partner,), config.pair_episodes, base + 100 + i)
        for i, (ego, partner, _) in enumerate(drawn)
    ]
    return named, pairs


@dataclass
class InferredCell:
    result: CellResult
    final_top1_E: np.ndarray  # the belief's top goal is the partner's goal at the episode's end
    updates_E: np.ndarray  # partner actions incorporated


def run_inferred(
    engine: InferenceEngine,
    scenarios: Sequence[Scenario],
    config: ValueConfig,
    *,
    progress: Callable[[int, int], None] | None = None,
) -> list[InferredCell]:
    """Every scenario's episodes with the inferred-goal ego, in one batched world."""
    env, belief_cfg = config.env, config.belief
    sizes = [s.episodes for s in scenarios]
    bounds = np.cumsum([0, *sizes])
    n_rows = int(bounds[-1])
    starts = np.concatenate([start_states(s.start_seed, s.episodes, 2) for s in scenarios])
    goals_BN = np.concatenate([np.tile(goal_indices(s.goals), (s.episodes, 1)) for s in scenarios])
    u_TBN = np.concatenate([uniforms(config.seed, s, config.max_steps) for s in scenarios], axis=1)
    world = BatchedParticleWorld(goals_BN, max_steps=config.max_steps)
    obs_BND = world.reset(starts)
    log_prior_G = prior_log_probs(GOAL_IDS)
    belief_BG = np.tile(initial_log_belief(log_prior_G, belief_cfg), (n_rows, 1))
    tally = EpisodeTally(starts, bounds[:-1].tolist())  # each scenario's first episode is recorded
    updates_B = np.zeros(n_rows, dtype=np.int64)
    previous: tuple[np.ndarray, np.ndarray] | None = None  # (ego observations, partner actions)

    for t in range(config.max_steps):
        active = np.flatnonzero(~tally.done_B)
        if active.size == 0:
            break
        if progress is not None:
            progress(t, int(active.size))
        actions_BN = np.zeros((n_rows, 2), dtype=np.int64)
        p_probs = partner_probs(
            engine, env, obs_BND[active, 1], goals_BN[active, 1], config.partner_alias
        )
        actions_BN[active, 1] = sample_actions(p_probs, u_TBN[t, active, 1])
        for r in active.tolist():
            if previous is not None:  # the session's step: update with a_{t-1} on o_{t-1}
                log_lik_1G = engine.goal_log_likelihoods(
                    env,
                    previous[0][r],
                    [1],
                    [int(previous[1][r])],
                    alias=config.alias,
                    temperature=belief_cfg.temperature,
                    noise=belief_cfg.noise,
                )
                belief_BG[r] = update_log_belief(
                    belief_BG[r][None], log_lik_1G, log_prior_G[None], belief_cfg
                )[0]
                updates_B[r] += 1
            ego_goal = GOAL_IDS[int(goals_BN[r, 0])]
            probs = ego_probs_with_belief(
                engine,
                env,
                ego_goal,
                obs_BND[r, 0],
                belief_BG[r],
                alias=config.alias,
                mass=config.blend_mass,
                max_goals=config.blend_max_goals,
            )
            actions_BN[r, 0] = sample_actions(probs[None], u_TBN[t, r : r + 1, 0])[0]
        previous = (obs_BND[:, 0].copy(), actions_BN[:, 1].copy())
        step = world.step(actions_BN)
        tally.record(step, world.state, goals_BN)
        obs_BND = step.next_obs_BND

    top_B = belief_BG.argmax(axis=1)
    cells = []
    for k, s in enumerate(scenarios):
        rows = np.arange(bounds[k], bounds[k + 1])
        result = tally.result(k, s, INFERRED, rows)
        cells.append(InferredCell(result, top_B[rows] == goals_BN[rows, 1], updates_B[rows]))
    return cells


def bootstrap_recovered(
    inferred: np.ndarray, announced: np.ndarray, sl: np.ndarray, *, draws: int, seed: int
) -> tuple[float, float, float]:
    """(point, lo, hi): (mean inferred − mean SL) / (mean announced − mean SL) and its 95 %
    percentile bootstrap interval over the paired units (resampled together)."""
    units = np.stack([np.asarray(inferred), np.asarray(announced), np.asarray(sl)]).astype(float)
    if units.ndim != 2 or units.shape[1] < 1:
        raise ValueError("bootstrap_recovered: expected three 1-d samples of one length >= 1")

    def ratio(means: np.ndarray) -> np.ndarray:
        gap = means[1] - means[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(gap != 0, (means[0] - means[2]) / gap, np.nan)

    point = float(ratio(units.mean(axis=1)))
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, units.shape[1], (draws, units.shape[1]))
    ratios = ratio(units[:, picks].mean(axis=2))
    ratios = ratios[np.isfinite(ratios)]
    if ratios.size == 0:
        return point, float("nan"), float("nan")
    lo, hi = np.percentile(ratios, [2.5, 97.5])
    return point, float(lo), float(hi)


@dataclass(frozen=True)
class Comparison:
    """Three methods on the same paired units (episodes or pairs)."""

    label: str
    units: int
    means: dict[str, dict[str, MeanSE]]  # method -> measure -> mean ± SE
    ego_success: dict[str, float]
    diffs: dict[str, tuple[MeanSE, float]]  # "measure: a - b" -> (paired diff, Wilcoxon p)
    recovered: tuple[float, float, float]  # team return: point, 95 % interval
    belief_top1: float | None  # the belief's top goal right at the episode's end


def compare(
    label: str,
    values: dict[str, dict[str, np.ndarray]],
    success: dict[str, np.ndarray],
    config: ValueConfig,
    belief_top1: float | None = None,
) -> Comparison:
    """`values[method][measure]`: one number per paired unit."""
    units = len(values["sl"]["team"])
    means = {m: {k: mean_se(v.tolist()) for k, v in values[m].items()} for m in VALUE_METHODS}
    diffs = {}
    for a, b in ((INFERRED, "aail"), (INFERRED, "sl"), ("aail", "sl")):
        for measure in MEASURES:
            x, y = values[a][measure], values[b][measure]
            diffs[f"{measure}: {a} − {b}"] = (paired_diff(x, y), wilcoxon_p(x, y))
    recovered = bootstrap_recovered(
        values[INFERRED]["team"],
        values["aail"]["team"],
        values["sl"]["team"],
        draws=config.bootstrap,
        seed=config.seed,
    )
    rates = {m: float(np.mean(success[m])) for m in VALUE_METHODS}
    return Comparison(label, units, means, rates, diffs, recovered, belief_top1)


def _episode_values(cell: CellResult) -> dict[str, np.ndarray]:
    return {
        "team": cell.team_E,
        "ego": cell.returns_EN[:, 0],
        "others": cell.returns_EN[:, 1:].sum(axis=1),
    }


@dataclass
class ValueResult:
    config: ValueConfig
    scenarios: dict[str, Comparison]  # aligned, non_aligned
    pair_groups: dict[str, Comparison]  # aligned pairs, non-aligned pairs
    cells: list[CellResult]
    wall_s: dict[str, float]


def run_value(
    engine: InferenceEngine, config: ValueConfig, *, progress: ProgressFn | None = None
) -> ValueResult:
    """SL, AAIL-announced and AAIL-inferred on the scenarios and pairs (module docstring)."""
    named, pairs = value_scenarios(config)
    chosen = named + pairs
    walls: dict[str, float] = {}

    def report(label: str) -> Callable[[int, int], None] | None:
        return None if progress is None else (lambda t, n: progress(label, t, n))

    started = time.perf_counter()
    baseline = run_cells(
        EngineBackend(engine),
        [Cell(s, m) for s in chosen for m in ("sl", "aail")],
        max_steps=config.max_steps,
        seed=config.seed,
        alias=config.alias,
        partner_alias=config.partner_alias,
        env=config.env,
        progress=report("sl, aail"),
    ).results
    walls["sl + aail announced"] = time.perf_counter() - started
    started = time.perf_counter()
    inferred = run_inferred(engine, chosen, config, progress=report(INFERRED))
    walls["aail inferred"] = time.perf_counter() - started

    by_name: dict[str, dict[str, CellResult]] = {}
    for cell in baseline + [c.result for c in inferred]:
        by_name.setdefault(cell.scenario.name, {})[cell.method] = cell
    top1 = {c.result.scenario.name: c.final_top1_E for c in inferred}
    scenarios = {}
    for s in named:
        cells = by_name[s.name]
        values = {m: _episode_values(cells[m]) for m in VALUE_METHODS}
        success = {m: cells[m].success_EN[:, 0] for m in VALUE_METHODS}
        scenarios[s.name] = compare(s.name, values, success, config, float(top1[s.name].mean()))
    groups = {}
    pair_cells = [c for s in pairs for c in by_name[s.name].values()]
    for label, kind in (("aligned pairs", "aligned"), ("non-aligned pairs", "non_aligned")):
        members = [u for u in units_of(pair_cells) if u.pair_class == kind]
        if not members:
            continue
        values = {
            m: {k: np.array([u.by_method[m][k] for u in members]) for k in MEASURES}
            for m in VALUE_METHODS
        }
        success = {m: np.array([u.by_method[m]["ego_success"] for u in members]) for m in values}
        hits = np.concatenate([top1[s.name] for u in members for s in u.scenarios])
        groups[label] = compare(label, values, success, config, float(hits.mean()))
    return ValueResult(config, scenarios, groups, baseline + [c.result for c in inferred], walls)
