"""The domain contract: what the trainer and the inference engine need from an environment.

PettingZoo describes how to *step* a world; it does not say which goals exist, how to build the
views each network is evaluated on, or how agent j sees the state agent i sees (the *perspective
transform* of paper §3.2). A `Domain` adds exactly that, so the trainer and the services stay free
of environment-specific code.

Every network in coexist is evaluated on a *view* built from the ego agent's observation:

- task view  (ego, other)   -> the ego's task network Q_t (one view per other agent, Q averaged);
  the same pair is the impact view of that partner: the impact network Q_i of the partner's
  goal reads `task_views(obs_BD, n_agents)[:, partner - 1]`;
- partner view (partner, ego) -> the partner's task network, whose soft value V^h is the impact
  reward of eq. 6 (the same pair seen from the partner's side);
- joint view: the ego's whole observation, for the joint-learner baseline (one net per goal combo).

What only the console needs (how to draw an env: `envs.registry.Drawing`) and what only the
trainer needs (`trainer.domain.EnvTrainer`) come with the environment's registration
(`envs.registry.EnvPlugin`), beside the domain and optional where they can be.

Shapes carry suffixes: `obs_BD` is a batch B of observations of size D.
"""

from __future__ import annotations

from typing import Literal, Protocol, runtime_checkable

import numpy as np

BlendNormalisation = Literal["standardise", "none"]


@runtime_checkable
class Domain(Protocol):
    """Environment description shared by trainer, model store metadata and inference engine."""

    name: str
    goals: tuple[str, ...]
    action_meanings: tuple[str, ...]
    max_agents: int
    pair_obs_dim: int
    # how AAIL's eq. 8 treats the Q-vectors it blends (`policy.blend`): "standardise" each over
    # the actions first, or "none" (raw Q, for rewards on one scale)
    blend_normalisation: BlendNormalisation
    # whether a reached goal stays reached whatever the ego does next (a served dish), so that its
    # task Q is flat from there on (AAIL-B then blends with a flat task Q: `policy.regret_bound`,
    # R3), or the ego must keep it (a target area it could leave)
    goal_is_final: bool

    @property
    def n_actions(self) -> int: ...

    def obs_dim(self, n_agents: int) -> int:
        """Length of one agent's observation in a world of `n_agents` agents."""
        ...

    def observation_layout(self, n_agents: int) -> list[str]:
        """One human-readable name per observation feature (documented in `GET /v1/envs`)."""
        ...

    def task_views(self, obs_BD: np.ndarray, n_agents: int) -> np.ndarray:
        """Views for the ego's task network, shape (B, K, pair_obs_dim), K >= 1."""
        ...

    def partner_view(self, obs_BD: np.ndarray, n_agents: int, partner: int) -> np.ndarray:
        """(partner, ego) view: the pair as the partner sees it, shape (B, pair_obs_dim)."""
        ...

    def goal_reached(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> np.ndarray | None:
        """Per row, whether the ego's own `goal` is reached in its observation, (B,) bool; None
        where observations cannot tell. AAIL-B blends only where it is (`policy.regret_bound`,
        the progress guard): elsewhere the ego acts with its task policy."""
        ...

    def goal_kept(self, obs_BD: np.ndarray, n_agents: int, goal: str) -> np.ndarray | None:
        """Per row and action, whether the ego's own `goal` is still reached after the action and
        can be kept from there, (B, A) bool; None where the environment cannot tell or the goal
        cannot be lost. AAIL-B takes no action that loses a reached goal where another keeps it
        (`policy.regret_bound`, R4)."""
        ...


class DomainCounts:
    """The parts of a `Domain` that follow from its fields alone; a domain may inherit them."""

    action_meanings: tuple[str, ...]
    max_agents: int

    @property
    def n_actions(self) -> int:
        return len(self.action_meanings)

    def _check_n(self, n_agents: int) -> None:
        """A ValueError naming `n_agents` unless the domain's worlds can hold that many."""
        if not 1 <= n_agents <= self.max_agents:
            raise ValueError(f"n_agents: expected 1..{self.max_agents}, got {n_agents}")


def check_goal(domain: Domain, goal: str, field: str = "goal") -> int:
    """Index of `goal` in the domain's catalogue, or a ValueError naming the field."""
    try:
        return domain.goals.index(goal)
    except ValueError:
        shown = ", ".join(domain.goals[:8]) + (", ..." if len(domain.goals) > 8 else "")
        quoted = repr(goal) if len(goal) <= 64 else f"{goal[:64]!r}… ({len(goal)} characters)"
        raise ValueError(
            f"{field}: unknown goal {quoted} for env {domain.name!r} (expected one of {shown})"
        ) from None
