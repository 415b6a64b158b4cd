"""Does an impact network push where its partner's value says it should? (particle world)

The impact gate's episodes (`trainer.particle.gates.impact_gates`) ask whether the partner does better
beside the impact-driven ego than beside a resting one. That passes a network that never chooses
some push at all, as long as it helps from enough starts: in the first zoo the network for the
centre cell `c2` never pushed left, so from the right of the centre it could not bring the ego to
the partner's influence area, and AAIL used it anyway. This check looks at the network itself,
state by state, against the signal it was trained on (eq. 6: the partner's soft value V^h).

From `direction_states` states spread over the world (ego and partner at uniform positions, at
rest), for each push a (up, down, left, right) the ego is moved by `probe_step` in a's direction
and the partner's value V^h (its task network on its own view, eq. 3) is evaluated again:

    gain_a = V^h(ego moved along a) - V^h(ego where it is)

| measure        | over which states                                     | what                      |
|----------------|-------------------------------------------------------|---------------------------|
| `toward_share` | informative: max_a gain_a > `min_value_gain`           | share where the network's |
|                | (the partner's value says some push helps)            | preferred action (arg max |
|                |                                                       | Q) gains >= half the best |
| `push_recall`  | per push: states where it is clearly the one needed   | share where the network   |
|                | (informative, and every other push gains <= a quarter | prefers exactly that push |
|                | of its gain); None with fewer than `min_needed_states`|                           |

A network passes when `toward_share >= toward_share_min` and every push's recall is at least
`push_recall_min`: no push it needs is dead. The probe moves the ego's position only, as a push
held for a few steps would; V^h sees the pair (partner, ego) as served.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from envs.particle.domain import PARTICLE
from envs.particle.world import ACTION_DIRECTIONS_A2, ACTION_MEANINGS, observations, random_states
from policy.qnet import StackedQNet
from policy.torch_ops import soft_value_t
from trainer.config import ImpactConfig

PUSHES: tuple[int, ...] = (1, 2, 3, 4)  # up, down, left, right (action 0 rests)
TOWARD_GAIN_SHARE = 0.5  # a preferred push "points toward" when it gains this share of the best
CLEAR_RATIO = 0.25  # a push is clearly needed when every other gains at most this share of it


@dataclass(frozen=True)
class DirectionCheck:
    """One impact network's direction figures (module docstring)."""

    toward_share: float
    push_recall: dict[str, float | None]  # push name -> recall, None: too few states need it
    informative_states: int
    passed: bool


@torch.no_grad()
def _forward(nets: StackedQNet, views_ND: np.ndarray) -> np.ndarray:
    """Every member on the same N views: (G, N, A)."""
    return nets(torch.from_numpy(views_ND.astype(np.float32))).numpy()


@torch.no_grad()
def _partner_values(nets: StackedQNet, ego_obs_ND: np.ndarray, alpha: float) -> np.ndarray:
    """V^h on the partner's view of each state (eq. 3), (G, N)."""
    q = nets(torch.from_numpy(PARTICLE.partner_view(ego_obs_ND, 2, 1).astype(np.float32)))
    return soft_value_t(q, alpha).numpy().astype(np.float64)


def push_gains(
    partner_task_nets: StackedQNet, state_N24: np.ndarray, probe_step: float, alpha: float
) -> np.ndarray:
    """gain_a of the module docstring for every member and state, (G, N, 4) in `PUSHES` order."""
    base = _partner_values(partner_task_nets, observations(state_N24)[:, 0], alpha)
    gains = []
    for push in PUSHES:
        moved = state_N24.copy()
        moved[:, 0, :2] = np.clip(moved[:, 0, :2] + probe_step * ACTION_DIRECTIONS_A2[push], 0, 1)
        gains.append(_partner_values(partner_task_nets, observations(moved)[:, 0], alpha) - base)
    return np.stack(gains, axis=-1)


def direction_checks(
    impact_nets: StackedQNet, partner_task_nets: StackedQNet, config: ImpactConfig, seed: int
) -> list[DirectionCheck]:
    """The check of the module docstring for each member g: impact network g beside partner
    task network g (both stacks hold one member per partner goal)."""
    if impact_nets.n_members != partner_task_nets.n_members:
        raise ValueError(
            f"partner_task_nets: expected one member per impact network "
            f"({impact_nets.n_members}), got {partner_task_nets.n_members}"
        )
    rng = np.random.default_rng(seed)
    state_N24 = random_states(rng, config.direction_states, 2)
    impact_views = PARTICLE.impact_view(observations(state_N24)[:, 0], 2, 1)
    preferred_GN = _forward(impact_nets, impact_views).argmax(axis=-1)
    gain_GNP = push_gains(partner_task_nets, state_N24, config.probe_step, config.alpha)
    return [_check(preferred_GN[g], gain_GNP[g], config) for g in range(gain_GNP.shape[0])]


def _check(preferred_N: np.ndarray, gain_NP: np.ndarray, config: ImpactConfig) -> DirectionCheck:
    best_N = gain_NP.max(axis=1)
    informative_N = best_N > config.min_value_gain
    # the gain of the preferred action (resting gains nothing)
    push_N = np.clip(preferred_N - PUSHES[0], 0, len(PUSHES) - 1)  # PUSHES are actions 1..4
    chosen_N = np.where(preferred_N > 0, gain_NP[np.arange(len(preferred_N)), push_N], 0.0)
    toward_N = chosen_N >= TOWARD_GAIN_SHARE * best_N
    toward_share = float(toward_N[informative_N].mean()) if informative_N.any() else 1.0
    second_N = np.sort(gain_NP, axis=1)[:, -2]
    clear_N = informative_N & (second_N <= CLEAR_RATIO * best_N)
    needed_N = np.asarray(PUSHES)[gain_NP.argmax(axis=1)]
    recall: dict[str, float | None] = {}
    for push in PUSHES:
        states = clear_N & (needed_N == push)
        enough = int(states.sum()) >= config.min_needed_states
        hits = float((preferred_N[states] == push).mean()) if enough else None
        recall[ACTION_MEANINGS[push]] = hits
    passed = toward_share >= config.toward_share_min and all(
        r is None or r >= config.push_recall_min for r in recall.values()
    )
    return DirectionCheck(toward_share, recall, int(informative_N.sum()), bool(passed))


def dead_pushes(check: DirectionCheck, config: ImpactConfig) -> list[str]:
    """The pushes whose recall falls short (names), for messages and reports."""
    return [n for n, r in check.push_recall.items() if r is not None and r < config.push_recall_min]
