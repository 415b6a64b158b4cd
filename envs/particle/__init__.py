"""The coexistence particle world of the paper (§4.1): N point masses in the unit square, each with
a goal (a cell, column or row of a 5×5 grid) that names a target area and an influence area.

| module         | what |
|----------------|------|
| `goals`        | the 35 goals, their target and influence boxes |
| `world`        | pure numpy dynamics, reward, observations, perspective transform |
| `batched`      | `BatchedParticleWorld`: B worlds stepped at once (trainer, evaluation) |
| `env`          | `ParticleCoexistenceEnv`: the PettingZoo `ParallelEnv` |
| `domain`       | `PARTICLE`: the `envs.base.Domain` (goal catalogue, pair views) |
| `scripted`     | straight-to-target controller (quality-gate reference, demo) |
| `scenarios`    | the paper's aligned / non-aligned / five-agent scenarios, paired starts |
| `render`       | RGB frames and GIFs |
"""

from envs.particle.batched import BatchedParticleWorld, StepResult
from envs.particle.domain import PARTICLE, ParticleDomain
from envs.particle.env import ParticleCoexistenceEnv, parallel_env
from envs.particle.goals import GOAL_IDS, INFLUENCE_BOXES_G4, TARGET_BOXES_G4, goal_index
from envs.particle.scenarios import (
    ALIGNED_PAIR,
    FIVE_AGENTS,
    NON_ALIGNED_PAIR,
    is_aligned,
    sample_goal_pairs,
    start_states,
)
from envs.particle.scripted import scripted_actions
from envs.particle.world import ACTION_MEANINGS, from_perspective, perspective

__all__ = [
    "ACTION_MEANINGS",
    "ALIGNED_PAIR",
    "FIVE_AGENTS",
    "GOAL_IDS",
    "INFLUENCE_BOXES_G4",
    "NON_ALIGNED_PAIR",
    "PARTICLE",
    "TARGET_BOXES_G4",
    "BatchedParticleWorld",
    "ParticleCoexistenceEnv",
    "ParticleDomain",
    "StepResult",
    "from_perspective",
    "goal_index",
    "is_aligned",
    "parallel_env",
    "perspective",
    "sample_goal_pairs",
    "scripted_actions",
    "start_states",
]
