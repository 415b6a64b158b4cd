"""Paper Fig. 6: the expected acceleration of a policy over a grid of ego positions.

For each ego position p on a G × G grid (cell centres of the unit square, velocity 0) and the
partner fixed at rest at the centre of its own target area (where it spends most of an
episode; the paper does not say where its partner was), the expected acceleration direction is

    E_π[d] = Σ_a π(a | s) d_a,   d_a = (0, 0), (0, 1), (0, -1), (-1, 0), (1, 0)

under four policies: the task policy (SL), the impact policy alone (Boltzmann of the impact
network at its training α, loaded from the store: the engine serves no "impact only" method),
NAIL and AAIL (from the backend, so a server run shows the server's policies).

| array         | shape    | meaning                                  |
|---------------|----------|------------------------------------------|
| `positions_B2`| (G*G, 2) | ego positions                            |
| `accel_B2`    | (G*G, 2) | expected acceleration direction per cell |
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.particle.domain import PARTICLE
from envs.particle.goals import TARGET_BOXES_G4, goal_index
from envs.particle.world import ACTION_DIRECTIONS_A2
from evaluation.backend import PolicyBackend
from model_store.naming import impact_model_name
from model_store.store import ModelStore
from policy.maths import boltzmann
from services.engine import DEFAULT_TEMPERATURE, ActRequest, PartnerSpec
from services.engine.networks import build_group, forward_group, load_net


@dataclass(frozen=True)
class DirectionField:
    label: str
    positions_B2: np.ndarray
    accel_B2: np.ndarray


def box_centre(goal: str) -> tuple[float, float]:
    x_lo, x_hi, y_lo, y_hi = TARGET_BOXES_G4[goal_index(goal)]
    return float(x_lo + x_hi) / 2, float(y_lo + y_hi) / 2


def grid_observations(partner_goal: str, grid: int) -> tuple[np.ndarray, np.ndarray]:
    """Ego positions (B, 2) on the grid and the 2-agent observations (B, 8) with the partner
    at rest at the centre of its target area."""
    if grid < 2:
        raise ValueError(f"grid: expected >= 2 cells per side, got {grid}")
    centres = (np.arange(grid) + 0.5) / grid
    xs, ys = np.meshgrid(centres, centres, indexing="xy")
    positions_B2 = np.stack([xs.ravel(), ys.ravel()], axis=1)
    obs_BD = np.zeros((positions_B2.shape[0], 8), dtype=np.float32)
    obs_BD[:, :2] = positions_B2
    obs_BD[:, 4:6] = box_centre(partner_goal)
    return positions_B2, obs_BD


def expected_direction(probs_BA: np.ndarray) -> np.ndarray:
    """Σ_a π(a) d_a per row, (B, 2)."""
    return probs_BA @ ACTION_DIRECTIONS_A2


def impact_probs(
    store: ModelStore, env: str, partner_goal: str, alias: str, obs_BD: np.ndarray
) -> np.ndarray:
    """Boltzmann policy of the impact network for `partner_goal` alone (its training α)."""
    version = store.resolve(f"{impact_model_name(env, partner_goal)}@{alias}")
    net = load_net(store, version)
    view_BD = PARTICLE.impact_view(obs_BD, 2, 1)
    q_BA = forward_group(build_group([net]), [view_BD.astype(np.float32)])[0]
    return boltzmann(q_BA.astype(np.float64), net.alpha or DEFAULT_TEMPERATURE)


def direction_fields(
    backend: PolicyBackend,
    store: ModelStore | None,
    ego_goal: str,
    partner_goal: str,
    *,
    grid: int = 15,
    alias: str = "production",
    env: str = "particle",
) -> list[DirectionField]:
    """Task, impact (when a store is given), NAIL and AAIL fields (module docstring)."""
    positions_B2, obs_BD = grid_observations(partner_goal, grid)
    fields = []
    for label, method in (
        ("task (SL)", "sl"),
        ("impact", None),
        ("NAIL", "nail"),
        ("AAIL", "aail"),
    ):
        if method is None:
            if store is None:
                continue
            probs_BA = impact_probs(store, env, partner_goal, alias, obs_BD)
        else:
            request = ActRequest(
                env=env,
                ego_goal=ego_goal,
                observations=obs_BD,
                partners=(PartnerSpec(1, goal=partner_goal),),
                method=method,  # type: ignore[arg-type]
                alias=alias,
            )
            probs_BA, _ = backend.probs(request)
        fields.append(DirectionField(label, positions_B2, expected_direction(probs_BA)))
    return fields
