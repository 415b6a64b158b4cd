"""The particle world as an `envs.base.Domain`: goal catalogue, observation layout and views.

Task and impact networks see *pair views* of 8 features, so one network serves scenes with any
number of agents:

| view          | built from the ego's observation (B, 4N)  | shape         |
|---------------|-------------------------------------------|---------------|
| task views    | [ego, other_j] for j = 1..N-1             | (B, N-1, 8)   |
| impact view   | [ego, other_k]                            | (B, 8)        |
| partner view  | [other_k, ego] (the pair as k sees it)    | (B, 8)        |

With N = 1 there is no other agent, but the task network still takes a pair. Its single task
view pairs the ego with a *phantom* at rest in the world's centre, `[0.5, 0.5, 0, 0]`. Why a
fixed phantom is safe: the ego's action moves only the ego, so it changes only the first term of
its task reward (its own distance to its target area); the influence term depends on where the
others are, which the ego cannot change. The task policy therefore barely depends on the other
agent, and a phantom that never moves cannot make it depend on the ego's action either. The centre
lies well inside the positions seen in training.

`recover_action` gives a partner's action between two consecutive observations (sessions that
infer goals from what partners do, when a client sends states rather than actions). The dynamics
are deterministic and an agent's step depends only on its own state and action, so the partner's
next `[x, y, vx, vy]` is predicted under each of the 5 actions with `world.step_state` and the
nearest prediction (Euclidean, all four features) wins. Two actions can predict the *same* next
state: pushing into a wall the agent rests against (the position is clipped and the velocity
component zeroed, exactly as at rest), or a state faster than `MAX_SPEED` (not reachable by the
dynamics, but a client may send one), where rest and a push along or against the motion are all
capped to the same velocity. Such ties (predictions within `SAME_PREDICTION_ATOL`: the two
computations may round differently) go to the lowest action index, rest before a push. With a
real robot's measured states the nearest prediction is a best guess, not a proof.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from envs.base import BlendNormalisation, DomainCounts, check_goal
from envs.particle.batched import MAX_AGENTS
from envs.particle.env import ParticleCoexistenceEnv
from envs.particle.goals import GOAL_IDS, TARGET_BOXES_G4
from envs.particle.scene import particle_frame, particle_scene
from envs.particle.world import (
    ACTION_DIRECTIONS_A2,
    ACTION_MEANINGS,
    DAMPING,
    DT,
    N_ACTIONS,
    STATE_DIM,
    integrate,
    step_state,
)
from envs.scene import Scene, SceneFrame

ALL_ACTIONS_A1 = np.arange(N_ACTIONS)[:, None]
# how far a resting agent still travels, in units of DT × its velocity after a step:
# Σ_k (1 - DAMPING)^k for k >= 1 (each rest keeps 1 - DAMPING of the velocity)
COAST = (1.0 - DAMPING) / DAMPING
SAME_PREDICTION_ATOL = 1e-9  # `recover_action`: predictions closer than this are one state
PHANTOM_4 = np.array([0.5, 0.5, 0.0, 0.0], dtype=np.float32)
_FEATURES = ("x", "y", "vx", "vy")


@functools.cache
def _pair_columns(n_agents: int) -> np.ndarray:
    """(N-1, 8) column indices of the pair views [ego, other_j], j = 1..N-1 (N >= 2)."""
    ego_4 = np.arange(STATE_DIM)
    columns = np.array(
        [np.concatenate([ego_4, j * STATE_DIM + ego_4]) for j in range(1, n_agents)], np.intp
    )
    columns.flags.writeable = False  # shared by every call
    return columns


@functools.cache
def _partner_columns(n_agents: int) -> np.ndarray:
    """(N-1, 8) column indices of the partner views [other_j, ego], j = 1..N-1 (N >= 2): the
    pair views with their two blocks swapped."""
    swapped = np.r_[STATE_DIM : 2 * STATE_DIM, 0:STATE_DIM]
    columns = np.ascontiguousarray(_pair_columns(n_agents)[:, swapped])
    columns.flags.writeable = False  # shared by every call
    return columns


@functools.cache
def _target_corners(goal_index: int) -> tuple[np.ndarray, np.ndarray]:
    """A target area's lower-left and upper-right corners, (x_min, y_min) and (x_max, y_max)."""
    x_lo, x_hi, y_lo, y_hi = TARGET_BOXES_G4[goal_index]
    low, high = np.array([x_lo, y_lo]), np.array([x_hi, y_hi])
    low.flags.writeable = high.flags.writeable = False  # shared by every call
    return low, high


def box_kept(ego_B4: np.ndarray, box_4: np.ndarray) -> np.ndarray:
    """(B, A) bool: whether after each action an agent at `ego_B4` ([x, y, vx, vy]) is inside
    the box [x_lo, x_hi, y_lo, y_hi] and stays inside if it rests from then on (the geometry of
    `ParticleDomain.goal_kept`; the goal monitors' labels use a shrunk box)."""
    next_BA4 = integrate(ego_B4[:, None].astype(np.float64), ACTION_DIRECTIONS_A2)
    coast_BA2 = np.clip(next_BA4[..., :2] + (COAST * DT) * next_BA4[..., 2:], 0.0, 1.0)
    ends_BAE2 = np.stack([next_BA4[..., :2], coast_BA2], axis=2)
    inside_BAE2 = (ends_BAE2 >= box_4[[0, 2]]) & (ends_BAE2 <= box_4[[1, 3]])
    return np.asarray(inside_BAE2.all(axis=(2, 3)))


class ParticleDomain(DomainCounts):
    """Domain description of the particle world (implements `envs.base.Domain`)."""

    name = "particle"
    goals: tuple[str, ...] = GOAL_IDS
    action_meanings: tuple[str, ...] = ACTION_MEANINGS
    max_agents = MAX_AGENTS
    pair_obs_dim = 2 * STATE_DIM
    # AAIL standardises each Q-vector before eq. 8 (policy.blend): the paper's evaluation here
    blend_normalisation: BlendNormalisation = "standardise"
    goal_is_final: bool = False  # the ego pays its distance to its target on every step

    def obs_dim(self, n_agents: int) -> int:
        self._check_n(n_agents)
        return STATE_DIM * n_agents

    def observation_layout(self, n_agents: int) -> list[str]:
        self._check_n(n_agents)
        owners = ["self"] + [f"other{j}" for j in range(1, n_agents)]
        return [f"{owner}.{feature}" for owner in owners for feature in _FEATURES]

    def _checked(self, obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
        """The observation as an array of shape (B, 4N), else a ValueError."""
        dim = self.obs_dim(n_agents)
        obs_BD = np.asarray(obs_BD)
        if obs_BD.ndim != 2 or obs_BD.shape[1] != dim:
            raise ValueError(
                f"obs_BD: expected shape (B, {dim}) for {n_agents} agents, got {obs_BD.shape}"
            )
        return obs_BD

    def _blocks(self, obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
        """Observation split into agent blocks, shape (B, N, 4)."""
        obs_BD = self._checked(obs_BD, n_agents)
        return obs_BD.reshape(obs_BD.shape[0], n_agents, STATE_DIM)

    def _check_partner(self, n_agents: int, partner: int) -> None:
        if not 1 <= partner <= n_agents - 1:
            raise ValueError(
                f"partner: expected an other agent's block 1..{n_agents - 1}, got {partner}"
            )

    def task_views(self, obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
        if n_agents == 1:
            blocks_BN4 = self._blocks(obs_BD, n_agents)
            batch = blocks_BN4.shape[0]
            phantom_BK4 = np.broadcast_to(PHANTOM_4.astype(blocks_BN4.dtype), (batch, 1, STATE_DIM))
            return np.concatenate([blocks_BN4[:, :1, :], phantom_BK4], axis=-1)
        # views of other agents are selections of the observation's columns: one take (the
        # same values as slicing the blocks and concatenating, in fewer numpy calls)
        return self._checked(obs_BD, n_agents).take(_pair_columns(n_agents), axis=1)

    def impact_view(self, obs_BD: np.ndarray, n_agents: int, partner: int) -> np.ndarray:
        obs_BD = self._checked(obs_BD, n_agents)
        self._check_partner(n_agents, partner)
        return obs_BD.take(_pair_columns(n_agents)[partner - 1], axis=1)

    def partner_view(self, obs_BD: np.ndarray, n_agents: int, partner: int) -> np.ndarray:
        obs_BD = self._checked(obs_BD, n_agents)
        self._check_partner(n_agents, partner)
        # one take (goal inference asks for every partner's view at every session step)
        return obs_BD.take(_partner_columns(n_agents)[partner - 1], axis=1)

    def goal_reached(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> np.ndarray:
        """Whether the ego is inside (or on the border of) its target area, (B,) bool. Its
        position is the observation's first two columns (AAIL-B, the default method, asks at
        every act: (B, 2) compared with the box's two corners)."""
        low_2, high_2 = _target_corners(check_goal(self, goal))
        xy_B2 = self._checked(obs_BD, n_agents)[:, :2]
        inside_B2 = (xy_B2 >= low_2) & (xy_B2 <= high_2)
        return inside_B2[:, 0] & inside_B2[:, 1]

    def goal_kept(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> np.ndarray:
        """(B, A) bool: whether after each action the ego is inside its target area and stays
        inside if it rests from then on. Resting, it coasts along a straight segment of length
        COAST × DT × |v| (walls only stop it), so each coordinate moves monotonically between
        the position after the action and the coast's end clipped to the world: both inside the
        box means the whole coast is."""
        box_4 = TARGET_BOXES_G4[check_goal(self, goal)]
        return box_kept(self._blocks(obs_BD, n_agents)[:, 0], box_4)

    def recover_action(
        self, prev_obs_D: np.ndarray, obs_D: np.ndarray, n_agents: int, partner: int
    ) -> int:
        """The partner's action between two consecutive ego observations: the action whose
        predicted next state is nearest the observed one, ties to the lowest index (module
        docstring)."""
        self._check_partner(n_agents, partner)
        before_4 = self._blocks(np.asarray(prev_obs_D)[None], n_agents)[0, partner]
        after_4 = self._blocks(np.asarray(obs_D)[None], n_agents)[0, partner]
        states_A14 = np.broadcast_to(np.asarray(before_4, dtype=np.float64), (N_ACTIONS, 1, 4))
        predicted_A4 = step_state(states_A14, ALL_ACTIONS_A1)[:, 0, :]
        gaps_A = np.sum((predicted_A4 - np.asarray(after_4, dtype=np.float64)) ** 2, axis=1)
        nearest_4 = predicted_A4[int(np.argmin(gaps_A))]
        # equal predictions differ by rounding only (~1e-16), distinct ones by far more
        same_A = np.abs(predicted_A4 - nearest_4).max(axis=1) <= SAME_PREDICTION_ATOL
        return int(np.argmax(same_A))  # the lowest action predicting the nearest next state

    def scene(self, env: Any) -> Scene:
        """The grid and the agents' target and influence areas (`envs.particle.scene`)."""
        return particle_scene(_particle_env(env).goals)

    def scene_frame(self, env: Any) -> SceneFrame:
        world = _particle_env(env)
        return particle_frame(world.goals, world.state().reshape(-1, STATE_DIM))


def _particle_env(env: Any) -> ParticleCoexistenceEnv:
    if not isinstance(env, ParticleCoexistenceEnv):
        raise TypeError(f"env: expected a particle world env, got {type(env).__name__}")
    return env


PARTICLE = ParticleDomain()
