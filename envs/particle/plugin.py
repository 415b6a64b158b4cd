"""The particle world's registration (`envs.registry.EnvPlugin`), the entry point `particle` of
the group `coexist.envs` in this project's `pyproject.toml`."""

from envs.particle import world
from envs.particle.domain import PARTICLE
from envs.particle.env import ParticleCoexistenceEnv
from envs.particle.scenarios import start_states
from envs.registry import EnvPlugin, StateAdapter

ENV = EnvPlugin(
    domain=PARTICLE,
    make_env=ParticleCoexistenceEnv,
    training="trainer.particle:TRAINER",
    drawing=PARTICLE,
    start_states=start_states,
    state_adapter=StateAdapter(("x", "y", "vx", "vy"), world.observations),
)
