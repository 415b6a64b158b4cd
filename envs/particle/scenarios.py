"""Scenarios of the paper's particle experiments (§4.2) and paired start states.

| name               | goals                            | paper                                 |
|--------------------|----------------------------------|---------------------------------------|
| `ALIGNED_PAIR`     | ego `c` (column), partner `c4`   | Fig. 5 left: the ego's target area is |
|                    |                                  | larger than, and contains, the        |
|                    |                                  | partner's influence area (`c0`)       |
| `NON_ALIGNED_PAIR` | ego `a2`, partner `b3`           | Fig. 5 right: target and influence    |
|                    |                                  | areas do not overlap                  |
| `FIVE_AGENTS`      | ego `a2`, partners `a0 b2 c4 e1` | Fig. 7: five agents, not aligned      |

`is_aligned` (any overlap of positive area) is the loose test of the first evaluation. The
evaluation classifies pairs strictly (`pair_class`), by the ego's target area T and the partner's
influence area I:

| class         | rule                               | pairs of the 35 × 35 |
|---------------|------------------------------------|----------------------|
| `aligned`     | I lies inside T                    | 85 (50 with I ≠ T: `room_to_help`) |
| `non_aligned` | T and I do not touch (a gap > 0)   | 720                  |
| `mixed`       | the rest: partial overlap, or only | 420                  |
|               | a shared edge or corner            |                      |

In an aligned pair the ego can sit where it is rewarded and where the partner wants it at the same
time; where I ≠ T it can also choose, inside its own target, the part the partner wants (there
is room to help). In a non-aligned pair every step spent helping is a step away from its target.

Start states are paired: `start_states(seed, ...)` gives the same starts for every method compared
on that seed. They are kept simple: positions uniform in the unit square, velocities zero, with no
rejection of starts that already lie inside a target area (that happens with the probability of the
area, and to every method alike).
"""

from __future__ import annotations

from typing import Literal

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


PairClass = Literal["aligned", "non_aligned", "mixed"]
PAIR_CLASSES: tuple[PairClass, ...] = ("aligned", "non_aligned", "mixed")


def _boxes(ego_goal: str, partner_goal: str) -> tuple[np.ndarray, np.ndarray]:
    return TARGET_BOXES_G4[goal_index(ego_goal)], INFLUENCE_BOXES_G4[goal_index(partner_goal)]


def pair_class(ego_goal: str, partner_goal: str) -> PairClass:
    """The strict class of a pair (module docstring). Boxes are rounded, so a shared edge is
    exactly a zero gap."""
    target, influence = _boxes(ego_goal, partner_goal)
    inside = (
        influence[0] >= target[0]
        and influence[1] <= target[1]
        and influence[2] >= target[2]
        and influence[3] <= target[3]
    )
    if inside:
        return "aligned"
    gap_x = max(target[0] - influence[1], influence[0] - target[1])
    gap_y = max(target[2] - influence[3], influence[2] - target[3])
    return "non_aligned" if max(gap_x, gap_y) > 0.0 else "mixed"


def room_to_help(ego_goal: str, partner_goal: str) -> bool:
    """An aligned pair whose target strictly contains the influence area (I ≠ T)."""
    target, influence = _boxes(ego_goal, partner_goal)
    return pair_class(ego_goal, partner_goal) == "aligned" and not np.array_equal(target, influence)


def pairs_of_class(kind: PairClass) -> list[tuple[str, str]]:
    """Every (ego goal, partner goal) pair of `kind`, in goal order."""
    if kind not in PAIR_CLASSES:
        raise ValueError(f"kind: expected one of {PAIR_CLASSES}, got {kind!r}")
    return [(e, p) for e in GOAL_IDS for p in GOAL_IDS if pair_class(e, p) == kind]


def sample_pairs_of_class(seed: int, kind: PairClass, k: int) -> list[tuple[str, str]]:
    """`k` distinct pairs of `kind` drawn with `seed` (all of them, in goal order, when `k` is at
    least the class's size)."""
    if k < 0:
        raise ValueError(f"k: expected >= 0, got {k}")
    pool = pairs_of_class(kind)
    if k >= len(pool):
        return pool
    picks = np.random.default_rng(seed).choice(len(pool), size=k, replace=False)
    return [pool[i] for i in sorted(picks.tolist())]


def sample_goal_sets(seed: int, k: int, n_agents: int) -> list[tuple[str, ...]]:
    """`k` goal sets of `n_agents` goals each, every goal drawn from the whole catalogue (two
    agents may share a goal, as strangers in one room may)."""
    if k < 0:
        raise ValueError(f"k: expected >= 0, got {k}")
    if not 2 <= n_agents <= MAX_AGENTS:
        raise ValueError(f"n_agents: expected 2..{MAX_AGENTS}, got {n_agents}")
    picks = np.random.default_rng(seed).integers(0, N_GOALS, size=(k, n_agents))
    return [tuple(GOAL_IDS[g] for g in row) for row in picks.tolist()]


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
