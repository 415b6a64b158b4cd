"""The particle world's motion and observations, for playing it with the SDK alone.

The server's environment (`envs.particle`, in the `coexist` distribution) takes its dynamics from
here, so a client that steps its own particles with `ParticleWorld` moves them exactly as the
server's env, trainer and evaluation do:

    from coexist_client import Client, RemotePolicy
    from coexist_client.particle import ParticleWorld

    goals = ["a2", "b3"]
    world = ParticleWorld(len(goals), seed=0)
    agents = [RemotePolicy(Client(), "particle", goals, agent=i, seed=i) for i in range(2)]
    for _ in range(50):
        world.step([agent(obs) for agent, obs in zip(agents, world.observations())])

State of one agent: `[x, y, vx, vy]`, positions in the unit square. One step of a damped point
mass: damp the velocity, add the action's acceleration, cap the speed, move, clip to the walls
(a position leaving [0, 1] is clipped back and that velocity component zeroed). Actions: 0 rest,
1 up, 2 down, 3 left, 4 right. Agent i's observation: its own block first, then the others in
agent order (what the server takes). The constants and why they are what they are:
`envs/particle/world.py`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

DT = 0.1
DAMPING = 0.25
ACCELERATION = 2.0
MAX_SPEED = 0.5
STATE_DIM = 4
ACTION_MEANINGS: tuple[str, ...] = ("rest", "up", "down", "left", "right")
ACTION_DIRECTIONS_A2 = np.array([[0, 0], [0, 1], [0, -1], [-1, 0], [1, 0]], dtype=np.float64)


def integrate(state_X4: np.ndarray, direction_X2: np.ndarray) -> np.ndarray:
    """One step of float64 states (..., 4) pushed along unit directions (..., 2) (zeros: rest);
    leading shapes broadcast. No checks: the callers check their inputs."""
    vel = state_X4[..., 2:] * (1.0 - DAMPING) + direction_X2 * (ACCELERATION * DT)
    speed = np.sqrt(np.sum(vel * vel, axis=-1, keepdims=True))
    vel = vel * np.minimum(1.0, MAX_SPEED / np.maximum(speed, 1e-12))
    pos = state_X4[..., :2] + vel * DT
    outside = (pos < 0.0) | (pos > 1.0)
    pos = np.clip(pos, 0.0, 1.0)
    vel = np.where(outside, 0.0, vel)  # a position can only leave through the wall it moves into
    return np.concatenate([pos, vel], axis=-1)


def observation_order(n_agents: int) -> np.ndarray:
    """(N, N) block order of every agent's observation: its own block first, others in order."""
    return np.array(
        [[i] + [j for j in range(n_agents) if j != i] for i in range(n_agents)], dtype=np.int64
    )


def observations(state_BN4: np.ndarray) -> np.ndarray:
    """Every agent's observation of states (..., N, 4), shape (..., N, 4N)."""
    n_agents = state_BN4.shape[-2]
    blocks = state_BN4[..., observation_order(n_agents), :]  # (..., N, N, 4)
    return blocks.reshape(*state_BN4.shape[:-2], n_agents, STATE_DIM * n_agents)


class ParticleWorld:
    """N particles in the unit square, stepped as the server's particle env steps them."""

    def __init__(self, n_agents: int, *, seed: int | None = None) -> None:
        if n_agents < 1:
            raise ValueError(f"n_agents: expected >= 1, got {n_agents}")
        self.n_agents = n_agents
        self.reset(seed)

    def reset(self, seed: int | None = None) -> None:
        """Positions uniform in the unit square, at rest."""
        self.state = np.zeros((self.n_agents, STATE_DIM), dtype=np.float64)
        self.state[:, :2] = np.random.default_rng(seed).random((self.n_agents, 2))

    def observations(self) -> list[list[float]]:
        """Each agent's observation (its own block first), as the server takes it."""
        return [list(map(float, row)) for row in observations(self.state)]

    def step(self, actions: Sequence[int]) -> None:
        """Move every agent by its action (0 rest, 1 up, 2 down, 3 left, 4 right)."""
        actions_N = np.asarray(actions)
        if actions_N.shape != (self.n_agents,) or not np.issubdtype(actions_N.dtype, np.integer):
            raise ValueError(f"actions: expected {self.n_agents} integers, got {list(actions)}")
        if actions_N.min() < 0 or actions_N.max() >= len(ACTION_MEANINGS):
            raise ValueError(f"actions: expected values in 0..{len(ACTION_MEANINGS) - 1}")
        self.state = integrate(self.state, ACTION_DIRECTIONS_A2[actions_N])
