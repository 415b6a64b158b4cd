"""Partners who are not coexist: the population the particle world's ego is judged against.

A method that is only ever judged with partners that are copies of its own networks is judged
in a world that agrees with it. People and other robots do not act as the ego's networks
predict; a partner type says how a partner of the evaluation acts instead. Every type pursues
the goal the ego was told (except `switching`, which abandons it), so the ego's announced goals
stay what a user would send.

| type          | how the partner acts                                                     |
|---------------|--------------------------------------------------------------------------|
| `same`        | the ego's own task networks (the ego's alias): coexist's copy           |
| `other_seed`  | task networks of another training seed (the partner population's alias) |
| `eps_0.1`     | `other_seed`, but a uniformly random action with probability 0.1         |
| `eps_0.3`     | the same with probability 0.3                                            |
| `hot`         | `other_seed`'s Boltzmann policy at 3 × its temperature                   |
| `scripted`    | `envs.particle.scripted`: straight to its target, blind to the others    |
| `switching`   | `other_seed`, but from step `SWITCH_STEP` on it pursues another goal     |
|               | (drawn per episode) that the ego is never told                           |
| `idle`        | rests every step (action 0): a person who stands still                  |

`partner_probs` gives, for the rows of one partner goal, the action distributions a type samples
from (the evaluation samples them with its common random numbers, `evaluation.rollout`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from envs.particle.goals import GOAL_IDS, N_GOALS
from envs.particle.scripted import scripted_actions
from services.engine import ActRequest

SWITCH_STEP = 10  # a `switching` partner changes its goal after this many steps
HOT_SCALE = 3.0  # a `hot` partner's temperature over its network's training α


@dataclass(frozen=True)
class PartnerType:
    """How a partner of the evaluation acts (module docstring)."""

    name: str
    # the task networks it acts with: the ego's own ("own"), the partner population's
    # ("population"), or none
    networks: Literal["own", "population"] | None = "population"
    epsilon: float = 0.0  # the probability of a uniformly random action
    temperature_scale: float = 1.0  # × the network's training α
    scripted: bool = False
    idle: bool = False
    switches: bool = False

    def alias(self, own: str, population: str) -> str | None:
        """The alias its networks resolve by, given the ego's and the population's."""
        return {"own": own, "population": population, None: None}[self.networks]


PARTNER_TYPES: dict[str, PartnerType] = {
    t.name: t
    for t in (
        PartnerType("same", networks="own"),
        PartnerType("other_seed"),
        PartnerType("eps_0.1", epsilon=0.1),
        PartnerType("eps_0.3", epsilon=0.3),
        PartnerType("hot", temperature_scale=HOT_SCALE),
        PartnerType("scripted", networks=None, scripted=True),
        PartnerType("switching", switches=True),
        PartnerType("idle", networks=None, idle=True),
    )
}


def partner_type(name: str) -> PartnerType:
    """The partner type called `name`; ValueError naming the known ones otherwise."""
    try:
        return PARTNER_TYPES[name]
    except KeyError:
        raise ValueError(
            f"partners: unknown partner type {name!r}, expected one of {sorted(PARTNER_TYPES)}"
        ) from None


def switched_goals(seed: int, goals_E: np.ndarray) -> np.ndarray:
    """Per episode, the goal a `switching` partner pursues after `SWITCH_STEP`: another goal
    than its announced one, drawn with `seed` (shape (E,), goal indices)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 4242]))
    shift = rng.integers(1, N_GOALS, size=goals_E.shape)
    return (goals_E + shift) % N_GOALS


def partner_probs(
    kind: PartnerType,
    alias: str | None,
    act: Callable[[ActRequest], np.ndarray],
    goal: str,
    obs_BD: np.ndarray,
    state_BN4: np.ndarray,
    slots_B: np.ndarray,
    n_actions: int,
    env: str = "particle",
) -> np.ndarray:
    """The action distributions, (B, A), of partners pursuing `goal` in rows whose own
    observations are `obs_BD` and whose world states are `state_BN4` (row b's partner is agent
    `slots_B[b]`); its networks resolve by `alias`; `act` answers engine requests."""
    rows = obs_BD.shape[0]
    if kind.idle:
        probs = np.zeros((rows, n_actions))
        probs[:, 0] = 1.0
        return probs
    if kind.scripted:
        goals_BN = np.full(state_BN4.shape[:2], GOAL_IDS.index(goal), dtype=np.int64)
        actions = scripted_actions(state_BN4, goals_BN)[np.arange(rows), slots_B]
        return np.eye(n_actions)[actions]
    if alias is None:
        raise ValueError(f"alias: partner type {kind.name!r} acts with networks, give their alias")
    request = ActRequest(env=env, ego_goal=goal, observations=obs_BD, method="sl", alias=alias)
    probs = act(request)
    if kind.temperature_scale != 1.0:
        # Boltzmann(Q, s·α) = Boltzmann(Q, α)^(1/s), renormalised: no need to know α
        with np.errstate(under="ignore"):
            probs = probs ** (1.0 / kind.temperature_scale)
        probs = probs / probs.sum(axis=1, keepdims=True)
    if kind.epsilon > 0.0:
        probs = (1.0 - kind.epsilon) * probs + kind.epsilon / n_actions
    return probs
