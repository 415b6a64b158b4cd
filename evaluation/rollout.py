"""Vectorised paired episodes: every (scenario, method) cell of a run steps in one batched world.

A *cell* is one scenario evaluated with one method for the controlled agent (agent 0). All cells
of a run share one `BatchedParticleWorld` (so they need the same agent count); row r belongs to
cell c = r // E_c and episode e. Per step there is one backend call per active cell (the ego's
`method`, its partners announced by goal) and one per partner goal (`sl` with the partner
population's alias; the rows of every cell and slot whose partner has that goal, each seen from
that partner's perspective).

| array             | shape        | meaning                                                  |
|-------------------|--------------|----------------------------------------------------------|
| `returns_EN`      | (E, N)       | sum of each agent's rewards over the episode             |
| `success_EN`      | (E, N)       | inside its own target area at the episode's last step    |
| `reached_EN`      | (E, N)       | inside its own target area after some step of the episode|
| `length_E`        | (E,)         | steps taken                                              |
| `solved_E`        | (E,)         | ended by the env's termination (all inside at one step)  |
| `trajectory_TN4`  | (T + 1, N, 4)| states of the recorded episode, its start included       |

Pairing and common random numbers: every method of a scenario starts from the same states, and
agent i in episode e at step t samples its action by inverse CDF from the *same* uniform
u[t, e, i] (drawn from `SeedSequence([seed, start_seed])`) whatever the method. Differences
between methods are then differences of policy, not of sampling luck, which tightens the
paired Wilcoxon tests. Finished episodes stop being sent to the backend.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from envs.particle.batched import BatchedParticleWorld, StepResult
from envs.particle.goals import GOAL_IDS, goal_indices
from envs.particle.scenarios import start_states
from envs.particle.world import ACTION_DIRECTIONS_A2, in_target
from evaluation.backend import ModelRecord, PolicyBackend
from evaluation.config import Scenario
from evaluation.partner_types import SWITCH_STEP, PartnerType, partner_probs, switched_goals
from policy.sampling import sample_actions
from services.engine import ActRequest, PartnerSpec

ProgressFn = Callable[[int, int], None]  # (step, active rows)


@dataclass(frozen=True)
class Cell:
    scenario: Scenario
    method: str


@dataclass
class CellResult:
    scenario: Scenario
    method: str
    returns_EN: np.ndarray
    success_EN: np.ndarray
    reached_EN: np.ndarray
    length_E: np.ndarray
    solved_E: np.ndarray
    trajectory_TN4: np.ndarray

    @property
    def team_E(self) -> np.ndarray:
        return self.returns_EN.sum(axis=1)


@dataclass
class RunOutput:
    results: list[CellResult]
    models: set[tuple[str, ModelRecord]] = field(default_factory=set)  # (alias, model)
    backend_calls: int = 0


class EpisodeTally:
    """The per-row bookkeeping of a batched rollout (the arrays of the module docstring), shared
    by `run_cells` and the inferred-goal rollout of `evaluation.inference.value`."""

    def __init__(self, starts_BN4: np.ndarray, record_rows: Sequence[int]) -> None:
        n_rows, n_agents = starts_BN4.shape[:2]
        self.returns_BN = np.zeros((n_rows, n_agents))
        self.reached_BN = np.zeros((n_rows, n_agents), dtype=bool)
        self.success_BN = np.zeros((n_rows, n_agents), dtype=bool)
        self.length_B = np.zeros(n_rows, dtype=np.int64)
        self.solved_B = np.zeros(n_rows, dtype=bool)
        self.done_B = np.zeros(n_rows, dtype=bool)
        self.record_rows = [int(r) for r in record_rows]
        self.trajectories = [[starts_BN4[r]] for r in self.record_rows]

    def record(self, step: StepResult, state_BN4: np.ndarray, goals_BN: np.ndarray) -> None:
        """Account one `world.step` result to the rows that were still running."""
        inside_BN = in_target(state_BN4, goals_BN)
        active_B = ~self.done_B
        self.returns_BN[active_B] += step.rewards_BN[active_B]
        self.reached_BN |= inside_BN & active_B[:, None]
        self.length_B[active_B] += 1
        finished_B = active_B & (step.terminated_B | step.truncated_B)
        self.success_BN[finished_B] = inside_BN[finished_B]
        self.solved_B[finished_B] = step.terminated_B[finished_B]
        self.done_B |= finished_B
        for k, r in enumerate(self.record_rows):
            if active_B[r]:
                self.trajectories[k].append(state_BN4[r])

    def result(self, k: int, scenario: Scenario, method: str, rows: np.ndarray) -> CellResult:
        """Cell k's result: its `rows`, its recorded episode."""
        return CellResult(
            scenario=scenario,
            method=method,
            returns_EN=self.returns_BN[rows],
            success_EN=self.success_BN[rows],
            reached_EN=self.reached_BN[rows],
            length_E=self.length_B[rows],
            solved_E=self.solved_B[rows],
            trajectory_TN4=np.stack(self.trajectories[k]),
        )


def uniforms(seed: int, scenario: Scenario, max_steps: int) -> np.ndarray:
    """The common random numbers of a scenario, (T, E, N) (module docstring)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, scenario.start_seed]))
    return rng.random((max_steps, scenario.episodes, scenario.n_agents))


class _Layout:
    """Which rows of the batched world belong to which cell, and the per-row constants."""

    def __init__(self, cells: Sequence[Cell], seed: int, max_steps: int) -> None:
        n_agents = {c.scenario.n_agents for c in cells}
        if len(n_agents) != 1:
            raise ValueError(f"cells: expected one agent count per run, got {sorted(n_agents)}")
        self.n_agents = n_agents.pop()
        sizes = [c.scenario.episodes for c in cells]
        bounds = np.cumsum([0, *sizes])
        self.rows = [np.arange(bounds[k], bounds[k + 1]) for k in range(len(cells))]
        self.n_rows = int(bounds[-1])
        starts: dict[str, np.ndarray] = {}
        noise: dict[str, np.ndarray] = {}
        for c in cells:
            s = c.scenario
            if s.name not in starts:
                starts[s.name] = start_states(s.start_seed, s.episodes, s.n_agents)
                noise[s.name] = uniforms(seed, s, max_steps)
        self.starts_BN4 = np.concatenate([starts[c.scenario.name] for c in cells])
        self.goals_BN = np.concatenate(
            [np.tile(goal_indices(c.scenario.goals), (c.scenario.episodes, 1)) for c in cells]
        )
        self.u_TBN = np.concatenate([noise[c.scenario.name] for c in cells], axis=1)


def run_cells(
    backend: PolicyBackend,
    cells: Sequence[Cell],
    *,
    max_steps: int,
    seed: int,
    alias: str = "production",
    partner_alias: str = "partners",
    env: str = "particle",
    record_episode: int = 0,
    progress: ProgressFn | None = None,
    regret_bound: float | None = None,
    budget: float | None = None,
    partner_type: PartnerType | None = None,
) -> RunOutput:
    """Run every cell's episodes to the end (module docstring); results in cell order.
    `regret_bound` is aail_bounded's ε, `budget` aail_budget's budget B (None: the engine's
    defaults); an aail_budget episode carries its budget state from step to step as a client
    of `/v1/act` does. Partners act as `partner_type` says (`evaluation.partner_types`;
    default: the task networks of `partner_alias`)."""
    partners = partner_type or PartnerType("population")
    partners_alias = partners.alias(alias, partner_alias)
    if not cells:
        raise ValueError("cells: expected at least one cell")
    layout = _Layout(cells, seed, max_steps)
    n_rows, n_agents = layout.n_rows, layout.n_agents
    world = BatchedParticleWorld(layout.goals_BN, max_steps=max_steps)
    n_actions = len(ACTION_DIRECTIONS_A2)
    switched = layout.goals_BN.copy()  # a switching partner's goals after SWITCH_STEP
    if partners.switches:
        for k, c in enumerate(cells):  # per scenario, so every method meets the same switch
            rows = layout.rows[k]
            for slot in range(1, n_agents):
                switched[rows, slot] = switched_goals(
                    c.scenario.start_seed + slot, layout.goals_BN[rows, slot]
                )
    obs_BND = world.reset(layout.starts_BN4)
    tally = EpisodeTally(
        layout.starts_BN4, [rows[min(record_episode, len(rows) - 1)] for rows in layout.rows]
    )
    out = RunOutput(results=[])
    ego_partners = [
        tuple(PartnerSpec(j, goal=g) for j, g in enumerate(c.scenario.partner_goals, start=1))
        for c in cells
    ]

    spent_B = np.zeros(n_rows)  # aail_budget's episode state per row (S, B, V)
    total_B = np.zeros(n_rows)
    value_B = np.zeros(n_rows)

    def act(request: ActRequest, rows: np.ndarray | None = None) -> np.ndarray:
        answer = backend.answer(request)
        out.models.update((request.alias, m) for m in answer.models)
        out.backend_calls += 1
        if rows is not None and answer.budget_spent_B is not None:
            spent_B[rows] = answer.budget_spent_B
            total_B[rows] = answer.budget_total_B
            value_B[rows] = answer.budget_value_B
        return answer.probs_BA

    for t in range(max_steps):
        active_B = ~tally.done_B
        if not active_B.any():
            break
        if progress is not None:
            progress(t, int(active_B.sum()))
        actions_BN = np.zeros((n_rows, n_agents), dtype=np.int64)
        live = [rows[active_B[rows]] for rows in layout.rows]
        for k, cell in enumerate(cells):
            rows = live[k]
            if rows.size == 0:
                continue
            request = ActRequest(
                env=env,
                ego_goal=cell.scenario.ego_goal,
                observations=obs_BND[rows, 0],
                partners=ego_partners[k],
                method=cell.method,  # type: ignore[arg-type]
                alias=alias,
                regret_bound=regret_bound if cell.method == "aail_bounded" else None,
            )
            if cell.method == "aail_budget":
                carried = t > 0  # the episode's first step sends no state
                request = replace(
                    request,
                    budget=budget,
                    budget_spent=spent_B[rows] if carried else None,
                    budget_total=total_B[rows] if carried else None,
                    budget_value=value_B[rows] if carried else None,
                )
            actions_BN[rows, 0] = sample_actions(act(request, rows), layout.u_TBN[t, rows, 0])
        if partners.switches and t == SWITCH_STEP:  # the partners' untold new goals
            world.set_goals(switched)
        goals_BN = world.goals
        live_B = np.flatnonzero(active_B)
        # one call per partner goal: the rows of every cell and slot whose partner pursues it
        by_goal: dict[int, list[tuple[np.ndarray, int]]] = {}
        for slot in range(1, n_agents):
            for g in np.unique(goals_BN[live_B, slot]).tolist():
                by_goal.setdefault(g, []).append((live_B[goals_BN[live_B, slot] == g], slot))
        for g, picked in by_goal.items():
            rows_R = np.concatenate([rows for rows, _ in picked])
            slots_R = np.concatenate([np.full(rows.size, slot) for rows, slot in picked])
            probs_RA = partner_probs(
                partners,
                partners_alias,
                act,
                GOAL_IDS[g],
                obs_BND[rows_R, slots_R],
                world.state[rows_R],
                slots_R,
                n_actions,
                env,
            )
            actions_BN[rows_R, slots_R] = sample_actions(probs_RA, layout.u_TBN[t, rows_R, slots_R])
        step = world.step(actions_BN)
        tally.record(step, world.state, world.goals)
        obs_BND = step.next_obs_BND

    for k, cell in enumerate(cells):
        out.results.append(tally.result(k, cell.scenario, cell.method, layout.rows[k]))
    return out
