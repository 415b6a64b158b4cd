"""Dynamics, reward and observations of the particle world (paper §4.1) as pure numpy functions.

Every function takes arrays with any leading batch shape (`B...`), so the PettingZoo env (B = 1)
and the batched simulator (B = thousands) share this one implementation.

State of one agent: `[x, y, vx, vy]`, positions in the unit square. One step of a damped point
mass (the integration order of the multi-agent particle envs): damp the velocity, add the
action's acceleration, cap the speed, move, then clip to the walls.

| constant       | value | why                                                              |
|----------------|-------|------------------------------------------------------------------|
| `DT`           | 0.1   | integration step; with the values below a step moves <= 0.05     |
| `DAMPING`      | 0.25  | velocity share lost per step: resting from full speed stops      |
|                |       | within 0.15 (less than a cell)                                   |
| `ACCELERATION` | 2.0   | a push adds 0.2 to the speed: full speed after 4 pushes, an      |
|                |       | opposite push nearly stops the agent in 2                        |
| `MAX_SPEED`    | 0.5   | Euclidean speed cap: from rest a side is crossed in 21 steps,    |
|                |       | the diagonal in 32 (alternating pushes; 28 at full speed)        |

The paper gives none of these numbers; they make crossing the world take a few dozen steps (well
inside the 1000-step episodes) while one action still visibly changes the motion.

Walls: a position leaving [0, 1] is clipped back and that velocity component is zeroed.

| action | meaning | acceleration direction |
|--------|---------|------------------------|
| 0      | rest    | (0, 0)                 |
| 1      | up      | (0, +1)                |
| 2      | down    | (0, -1)                |
| 3      | left    | (-1, 0)                |
| 4      | right   | (+1, 0)                |

Reward (paper §4.1): r_i = -dist(agent i, target area of i) - Σ_{j≠i} dist(agent j, influence
area of i), with dist the Euclidean distance to the closest point of the area (0 inside).

Observation of agent i, shape (4N,): its own `[x, y, vx, vy]` first, then the other agents'
blocks in agent order. `perspective` re-orders an ego's observation into another agent's.
"""

from __future__ import annotations

import functools

import numpy as np

# the motion itself lives in the SDK (`coexist_client.particle`): a client that plays the particle
# world with the SDK alone moves its particles with the very same code
# (`X as X`: re-exported for the env, trainer and evaluation modules that import them from here)
from coexist_client.particle import ACCELERATION as ACCELERATION
from coexist_client.particle import ACTION_DIRECTIONS_A2 as ACTION_DIRECTIONS_A2
from coexist_client.particle import ACTION_MEANINGS as ACTION_MEANINGS
from coexist_client.particle import DAMPING as DAMPING
from coexist_client.particle import DT as DT
from coexist_client.particle import MAX_SPEED as MAX_SPEED
from coexist_client.particle import STATE_DIM as STATE_DIM
from coexist_client.particle import integrate as integrate

from envs.particle.goals import INFLUENCE_BOXES_G4, N_GOALS, TARGET_BOXES_G4

N_ACTIONS = len(ACTION_MEANINGS)


def _check_state(state_BN4: np.ndarray) -> None:
    if state_BN4.ndim < 2 or state_BN4.shape[-1] != STATE_DIM:
        raise ValueError(f"state: expected shape (..., N, 4), got {state_BN4.shape}")


def _check_per_agent(name: str, array_BN: np.ndarray, state_BN4: np.ndarray, bound: int) -> None:
    if array_BN.shape != state_BN4.shape[:-1]:
        raise ValueError(f"{name}: expected shape {state_BN4.shape[:-1]}, got {array_BN.shape}")
    if not np.issubdtype(array_BN.dtype, np.integer):
        raise ValueError(f"{name}: expected integers, got dtype {array_BN.dtype}")
    if array_BN.size and (array_BN.min() < 0 or array_BN.max() >= bound):
        raise ValueError(f"{name}: expected values in 0..{bound - 1}")


def step_state(state_BN4: np.ndarray, actions_BN: np.ndarray) -> np.ndarray:
    """One step of every agent: damped point mass, speed cap, walls. Returns a new array."""
    state_BN4 = np.asarray(state_BN4, dtype=np.float64)
    actions_BN = np.asarray(actions_BN)
    _check_state(state_BN4)
    _check_per_agent("actions", actions_BN, state_BN4, N_ACTIONS)
    return integrate(state_BN4, ACTION_DIRECTIONS_A2[actions_BN])


def box_distance(points_X2: np.ndarray, boxes_X4: np.ndarray) -> np.ndarray:
    """Euclidean distance from points to the closest point of axis-aligned boxes (0 inside).

    Boxes are (x_min, x_max, y_min, y_max); leading shapes broadcast against each other.
    """
    x, y = points_X2[..., 0], points_X2[..., 1]
    dx = np.maximum(np.maximum(boxes_X4[..., 0] - x, x - boxes_X4[..., 1]), 0.0)
    dy = np.maximum(np.maximum(boxes_X4[..., 2] - y, y - boxes_X4[..., 3]), 0.0)
    return np.sqrt(dx * dx + dy * dy)


def validate_goals(state_BN4: np.ndarray, goals_BN: np.ndarray) -> np.ndarray:
    """`goals_BN` as an array after checking it holds one goal index per agent of `state_BN4`."""
    goals_BN = np.asarray(goals_BN)
    _check_state(state_BN4)
    _check_per_agent("goals", goals_BN, state_BN4, N_GOALS)
    return goals_BN


def rewards(state_BN4: np.ndarray, goals_BN: np.ndarray) -> np.ndarray:
    """Reward of every agent in `state_BN4` (paper §4.1, the reward r_i), shape (..., N)."""
    goals_BN = validate_goals(state_BN4, goals_BN)
    pos_BN2 = state_BN4[..., :2]
    own_BN = box_distance(pos_BN2, TARGET_BOXES_G4[goals_BN])
    # others_BNN[..., i, j] = distance of agent j to the influence area of agent i
    influence_BN14 = INFLUENCE_BOXES_G4[goals_BN][..., :, None, :]
    others_BNN = box_distance(pos_BN2[..., None, :, :], influence_BN14)
    n_agents = state_BN4.shape[-2]
    others_BN = np.sum(others_BNN * _off_diagonal(n_agents), axis=-1)  # j ≠ i
    return -own_BN - others_BN


def in_target(state_BN4: np.ndarray, goals_BN: np.ndarray) -> np.ndarray:
    """Whether each agent is inside (or on the border of) its target area, shape (..., N)."""
    goals_BN = validate_goals(state_BN4, goals_BN)
    return box_distance(state_BN4[..., :2], TARGET_BOXES_G4[goals_BN]) <= 0.0


def _front_order(n_agents: int, first: int) -> np.ndarray:
    """Block order that puts block `first` in front and keeps the others in order."""
    return np.array([first] + [j for j in range(n_agents) if j != first], dtype=np.int64)


@functools.cache
def _observation_order(n_agents: int) -> np.ndarray:
    """(N, N) block order of every agent's observation (cached: it is used every step)."""
    return np.stack([_front_order(n_agents, i) for i in range(n_agents)])


@functools.cache
def _off_diagonal(n_agents: int) -> np.ndarray:
    return 1.0 - np.eye(n_agents)


def observations(state_BN4: np.ndarray) -> np.ndarray:
    """Every agent's observation, shape (..., N, 4N): own block first, then the others in order."""
    _check_state(state_BN4)
    n_agents = state_BN4.shape[-2]
    blocks = state_BN4[..., _observation_order(n_agents), :]  # (..., N, N, 4)
    return blocks.reshape(*state_BN4.shape[:-2], n_agents, STATE_DIM * n_agents)


def _reorder_blocks(obs_BD: np.ndarray, n_agents: int, order: np.ndarray) -> np.ndarray:
    obs_BD = np.asarray(obs_BD)
    if obs_BD.ndim < 1 or obs_BD.shape[-1] != STATE_DIM * n_agents:
        raise ValueError(
            f"obs: expected last dimension 4 * n_agents = {STATE_DIM * n_agents}, "
            f"got shape {obs_BD.shape}"
        )
    blocks = obs_BD.reshape(*obs_BD.shape[:-1], n_agents, STATE_DIM)[..., order, :]
    return blocks.reshape(obs_BD.shape)


def _check_agent(n_agents: int, agent: int) -> None:
    if not 0 <= agent < n_agents:
        raise ValueError(f"agent: expected 0..{n_agents - 1}, got {agent}")


def perspective(obs_BD: np.ndarray, n_agents: int, i: int) -> np.ndarray:
    """Agent i's observation built from the ego's (paper §3.2, "we transform the state").

    `i` indexes the ego's layout (0 = the ego itself). Block i moves to the front, the other blocks
    keep their order, so for the ego being agent 0 this is exactly `observations(state)[..., i, :]`.
    """
    _check_agent(n_agents, i)
    return _reorder_blocks(obs_BD, n_agents, _front_order(n_agents, i))


def from_perspective(obs_BD: np.ndarray, n_agents: int, i: int) -> np.ndarray:
    """Inverse of `perspective`: the ego's observation back from agent i's view of it."""
    _check_agent(n_agents, i)
    return _reorder_blocks(obs_BD, n_agents, np.argsort(_front_order(n_agents, i)))


def random_states(
    rng: np.random.Generator, batch_shape: int | tuple[int, ...], n_agents: int
) -> np.ndarray:
    """Start states: positions uniform in the unit square, velocities zero; shape (*batch, N, 4)."""
    shape = (batch_shape,) if isinstance(batch_shape, int) else tuple(batch_shape)
    state = np.zeros((*shape, n_agents, STATE_DIM), dtype=np.float64)
    state[..., :2] = rng.random((*shape, n_agents, 2))
    return state
