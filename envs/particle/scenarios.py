"""Scenarios of the paper's particle experiments (§4.2) and paired start states.

| name               | goals                            | paper                                 |
|--------------------|----------------------------------|---------------------------------------|
| `ALIGNED_PAIR`     | ego `c` (column), partner `c4`   | Fig. 5 left: the ego's target area is |
|                    |                                  | larger than, and contains, the        |
|                    |                                  | partner's influence area (`c0`)       |
| `NON_ALIGNED_PAIR` | ego `a2`, partner `b3`           | Fig. 5 right: target and influence    |
|                    |                                  | areas do not overlap                  |
| `FIVE_AGENTS`      | ego `a2`, partners `a0 b2 c4 e1` | Fig. 7: five agents, not aligned      |

A pair is *aligned* when the ego's target area overlaps the partner's influence area with positive
area: the ego can then sit where it is rewarded and where the partner wants it at the same time.

Start states are paired: `start_states(seed, ...)` gives the same starts for every method compared
on that seed. They are kept simple: positions uniform in the unit square, velocities zero, with no
rejection of starts that already lie inside a target area (that happens with the probability of the
area, and to every method alike).
"""

from __future__ import annotations

import numpy as np

from envs.particle.batched import MAX_AGENTS
from envs.particle.goals import GOAL_IDS, INFLUENCE_BOXES_G4, N_GOALS, TARGET_BOXES_G4, goal_index
from envs.particle.world import random_states

ALIGNED_PAIR: tuple[str, str] = ("c", "c4")
NON_ALIGNED_PAIR: tuple[str, str] = ("a2", "b3")
FIVE_AGENTS: tuple[str, tuple[str, ...]] = ("a2", ("a0", "b2", "c4", "e1"))


def overlap_area(box_a: np.ndarray, box_b: np.ndarray) -> float:
    """Area of the intersection of two (x_min, x_max, y_min, y_max) boxes (0 if disjoint)."""
    width = min(box_a[1], box_b[1]) - max(box_a[0], box_b[0])
    height = min(box_a[3], box_b[3]) - max(box_a[2], box_b[2])
    return float(max(width, 0.0) * max(height, 0.0))


def is_aligned(ego_goal: str, partner_goal: str) -> bool:
    """Whether the ego's target area overlaps the partner's influence area with positive area."""
    target = TARGET_BOXES_G4[goal_index(ego_goal)]
    influence = INFLUENCE_BOXES_G4[goal_index(partner_goal)]
    return overlap_area(target, influence) > 0.0  # boxes are rounded: shared edges give exactly 0


def start_states(seed: int, n_episodes: int, n_agents: int) -> np.ndarray:
    """Paired start states, shape (E, N, 4): uniform positions, zero velocities, fixed by `seed`."""
    if n_episodes < 1:
        raise ValueError(f"n_episodes: expected >= 1, got {n_episodes}")
    if not 1 <= n_agents <= MAX_AGENTS:
        raise ValueError(f"n_agents: expected 1..{MAX_AGENTS}, got {n_agents}")
    return random_states(np.random.default_rng(seed), n_episodes, n_agents)


def sample_goal_pairs(seed: int, k: int) -> list[tuple[str, str, bool]]:
    """`k` distinct (ego goal, partner goal, aligned) triples from the 35 × 35 combinations."""
    if not 1 <= k <= N_GOALS * N_GOALS:
        raise ValueError(f"k: expected 1..{N_GOALS * N_GOALS}, got {k}")
    picks = np.random.default_rng(seed).choice(N_GOALS * N_GOALS, size=k, replace=False)
    pairs = [(GOAL_IDS[p // N_GOALS], GOAL_IDS[p % N_GOALS]) for p in picks.tolist()]
    return [(ego, partner, is_aligned(ego, partner)) for ego, partner in pairs]
