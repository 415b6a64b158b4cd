"""Episodes of any registered environment with two agents: the ego acting by one method, its
partner by its own task network.

| agent         | policy                                                                     |
|---------------|----------------------------------------------------------------------------|
| 0 (the ego)   | `method` with agent 1 as its partner, the partner's goal announced          |
| 1 (partner)   | `sl` on its own goal: its task network's Boltzmann policy at its training α |

Every method plays the same episodes: pair p's episode e starts from
`envs.registry.episode_resets(env, seed + 1000 p, episodes, 2)[e]` and agent i samples its
action at step t with the uniform `U[p, e, t, i]` (common random numbers drawn once from
`seed`), so the methods' differences are paired by episode. The envs of one method step in
lockstep: per step, one engine request per goal pair for the egos (rows: that pair's live
episodes) and one per partner goal for the partners.

Per episode: each agent's return (the sum of its rewards) and whether its own goal is reached
at the last step (`Domain.goal_reached` on its final observation).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from envs.registry import episode_resets, get_domain, make_env
from evaluation.backend import PolicyBackend
from services.engine.messages import ActRequest, PartnerSpec

Pair = tuple[str, str]  # (the ego's goal, the partner's goal)
PAIR_SEED_STRIDE = 1000  # pair p's starts are seeded seed + 1000 p: distinct for < 1000 episodes


@dataclass(frozen=True, eq=False)
class PairEpisodes:
    """One method's episodes: arrays (P pairs, E episodes)."""

    method: str
    ego_success: np.ndarray  # bool
    ego_return: np.ndarray
    partner_return: np.ndarray
    partner_success: np.ndarray  # bool
    length: np.ndarray  # int

    @property
    def team_return(self) -> np.ndarray:
        return self.ego_return + self.partner_return


def goal_pairs(goals: Sequence[str], pairs: int | None, seed: int) -> list[Pair]:
    """Every ordered pair of distinct goals, or (`pairs` fewer than those) a draw of `pairs` of
    them without replacement, seeded by `seed`, in the listed order."""
    every = [(a, b) for a in goals for b in goals if a != b]
    if pairs is None or pairs >= len(every):
        return every
    chosen = np.random.default_rng([seed, 1]).choice(len(every), size=pairs, replace=False)
    return [every[i] for i in sorted(chosen)]


def _sample(probs_BA: np.ndarray, u_B: np.ndarray) -> np.ndarray:
    """Inverse-CDF sampling: row b's action is the first whose cumulative probability exceeds
    u_b (the same u gives the same action wherever two methods' policies agree)."""
    cdf = np.cumsum(probs_BA, axis=1)
    cdf[:, -1] = np.inf  # rounding must not leave u above the last cumulative sum
    return (u_B[:, None] < cdf).argmax(axis=1)


def run_method(
    backend: PolicyBackend,
    env: str,
    pairs: Sequence[Pair],
    method: str,
    *,
    episodes: int,
    seed: int,
    max_steps: int,
    alias: str,
    regret_bound: float | None = None,
    advance: Callable[[int, int], None] | None = None,
) -> PairEpisodes:
    """`episodes` episodes of `method` on every pair (module docstring)."""
    domain = get_domain(env)
    P, E, n = len(pairs), episodes, 2
    uniforms = np.random.default_rng([seed, 2]).random((P, E, max_steps, n))
    envs: list[list[Any]] = []
    obs = np.zeros((P, E, n, domain.obs_dim(n)))
    for p, goals in enumerate(pairs):
        resets = episode_resets(env, seed + PAIR_SEED_STRIDE * p, E, n)
        row = []
        for e in range(E):
            world = make_env(env, list(goals), max_steps=max_steps)
            observations, _ = world.reset(**resets[e])
            for i, agent in enumerate(world.possible_agents):
                obs[p, e, i] = observations[agent]
            row.append(world)
        envs.append(row)
    returns = np.zeros((P, E, n))
    length = np.zeros((P, E), dtype=int)
    live = np.ones((P, E), dtype=bool)
    # aail_budget's episode state, carried per row from one step to the next (None at t = 0)
    budget: np.ndarray | None = None
    for t in range(max_steps):  # the env truncates at max_steps (`EnvPlugin.make_env`)
        if not live.any():
            break
        actions = np.zeros((P, E, n), dtype=int)
        for p, (ego_goal, partner_goal) in enumerate(pairs):
            rows = np.flatnonzero(live[p])
            if rows.size == 0:
                continue
            state = {} if budget is None else _budget_state(budget[p, rows])
            ego = backend.answer(
                ActRequest(
                    env=env,
                    ego_goal=ego_goal,
                    observations=obs[p, rows, 0],
                    partners=(PartnerSpec(index=1, goal=partner_goal),),
                    method=method,  # type: ignore[arg-type]
                    regret_bound=regret_bound,
                    alias=alias,
                    **state,
                )
            )
            spent, total, value = ego.budget_spent_B, ego.budget_total_B, ego.budget_value_B
            if spent is not None and total is not None and value is not None:
                if budget is None:
                    budget = np.full((P, E, 3), np.nan)
                budget[p, rows] = np.stack([spent, total, value], axis=1)
            actions[p, rows, 0] = _sample(ego.probs_BA, uniforms[p, rows, t, 0])
        # the partners act on their own goals alone: one request per partner goal, every pair's
        for partner_goal in sorted({g for _, g in pairs}):
            at = live & np.array([g == partner_goal for _, g in pairs])[:, None]
            if not at.any():
                continue
            partner = backend.answer(
                ActRequest(env=env, ego_goal=partner_goal, observations=obs[at][:, 1], alias=alias)
            )
            actions[..., 1][at] = _sample(partner.probs_BA, uniforms[..., t, 1][at])
        for p in range(P):
            for e_live in np.flatnonzero(live[p]):
                e = int(e_live)
                world = envs[p][e]
                agents = world.possible_agents
                step = {a: int(actions[p, e, i]) for i, a in enumerate(agents) if a in world.agents}
                observations, rewards, _, _, _ = world.step(step)
                for i, agent in enumerate(agents):
                    returns[p, e, i] += rewards.get(agent, 0.0)
                    if agent in observations:
                        obs[p, e, i] = observations[agent]
                length[p, e] += 1
                if not world.agents:
                    live[p, e] = False
                    world.close()
        if advance is not None:
            advance(t + 1, int(live.sum()))
    success = np.zeros((P, E, n), dtype=bool)
    for p, goals in enumerate(pairs):
        for i, goal in enumerate(goals):
            reached = domain.goal_reached(obs[p, :, i], n, goal)
            success[p, :, i] = False if reached is None else reached
    return PairEpisodes(
        method=method,
        ego_success=success[..., 0],
        ego_return=returns[..., 0],
        partner_return=returns[..., 1],
        partner_success=success[..., 1],
        length=length,
    )


def _budget_state(rows: np.ndarray) -> dict[str, Any]:
    """aail_budget's carried state of these rows, none at an episode's first step."""
    if np.isnan(rows).any():
        return {}
    return {"budget_spent": rows[:, 0], "budget_total": rows[:, 1], "budget_value": rows[:, 2]}
