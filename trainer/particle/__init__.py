"""The trainer's particle world: rollouts, gates and learners (`trainer.domain.EnvTrainer`)."""

from trainer.particle.learners import ParticleTrainer

TRAINER = ParticleTrainer()
