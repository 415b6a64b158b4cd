"""The numbers of the generic machinery: soft-Q hyperparameters (`trainer.config.SoftQConfig`)
and the thresholds of its gates (`trainer.generic.gates`), per environment.

The defaults are the particle world's soft-Q numbers (`trainer.config`); an environment sets
what its reward's scale and its episodes' length call for. Gate thresholds default to the
weakest meaningful test: a task network must beat a uniformly random ego, an impact network
must leave its partner better off than a uniformly random ego does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from trainer.config import SoftQConfig


@dataclass(frozen=True)
class GenericConfig(SoftQConfig):
    """Soft-Q hyperparameters of a learner of the generic machinery."""

    env: str = ""
    """The environment trained in (filled in from the registration's name)."""

    def env_name(self) -> str:
        return self.env


@dataclass(frozen=True)
class GenericTaskConfig(GenericConfig):
    """Task networks (paper §3.1): the ego learns its goal beside a partner with a random goal
    that acts uniformly at random (there is no scripted partner to call on)."""

    success_threshold: float = 0.0
    """Gate: share of gate episodes in which the ego reaches its goal at some step
    (`Domain.goal_reached`); 0 judges nothing (nor does a domain whose observations cannot
    tell)."""
    return_margin: float = 0.0
    """Gate: the network's mean return must exceed a uniformly random ego's on the same starts
    by more than this (in the env's reward units)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 0.0 <= self.success_threshold <= 1.0:
            raise ValueError(
                f"success_threshold: expected a share in [0, 1], got {self.success_threshold}"
            )


@dataclass(frozen=True)
class GenericImpactConfig(GenericConfig):
    """Impact networks (paper §3.2, eqs. 6-7): the ego learns the change of the partner's soft
    value while the partner acts with its frozen task network. A quarter of random actions and
    shorter episodes, as the particle world's impact learner found it needed
    (`trainer.config.ImpactConfig`)."""

    total_steps: int = 8_000
    explore_eps: float = 0.3
    episode_steps: int = 60
    partner_gain: float = 0.0
    """Gate: the partner's mean return beside the network must exceed its mean return beside a
    uniformly random ego, on the same starts, by more than this."""


@dataclass(frozen=True)
class GenericTraining:
    """How an environment trains with the generic machinery: its registration's `training`."""

    task: GenericTaskConfig = field(default_factory=GenericTaskConfig)
    impact: GenericImpactConfig = field(default_factory=GenericImpactConfig)
    production_parents_only: bool = False
    """Whether an impact network may only learn beside a task network that passed its gate
    (`trainer.domain.EnvTrainer.production_parents_only`)."""
