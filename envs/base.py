"""The domain contract: what the trainer and the inference engine need from an environment.

PettingZoo describes how to *step* a world; it does not say which goals exist, how to build the
views each network is evaluated on, or how agent j sees the state agent i sees (the *perspective
transform* of paper §3.2). A `Domain` adds exactly that, so the trainer and the services stay free
of environment-specific code.

Every network in coexist is evaluated on a *view* built from the ego agent's observation:

- task view  (ego, other)   -> the ego's task network Q_t (one view per other agent, Q averaged);
- impact view (ego, partner) -> the impact network Q_i for that partner's goal;
- partner view (partner, ego) -> the partner's task network, whose soft value V^h is the impact
  reward of eq. 6 (the same pair seen from the partner's side);
- joint view: the ego's whole observation, for the joint-learner baseline (one net per goal combo).

A domain also draws its envs for the web console (`scene`, `scene_frame`: shapes in the world's
units, `envs.scene`), so the console needs no environment-specific code either.

Shapes carry suffixes: `obs_BD` is a batch B of observations of size D.
"""

from __future__ import annotations

from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np

from envs.scene import Scene, SceneFrame

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

    def impact_view(self, obs_BD: np.ndarray, n_agents: int, partner: int) -> np.ndarray:
        """(ego, partner) view for an impact network, shape (B, pair_obs_dim); partner in 1..N-1.
        The same pair as the task view of that agent: `task_views(obs_BD, n_agents)[:, partner -
        1]` (the inference engine reads the impact views from there, in one pass)."""
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

    def scene(self, env: Any) -> Scene:
        """What does not move in `env` (an env of this domain, from `envs.registry.make_env`),
        as shapes to draw (`envs.scene`): the web console paints it once per episode."""
        ...

    def scene_frame(self, env: Any) -> SceneFrame:
        """Where `env`'s agents and objects are now, in the units of `scene(env)`."""
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
