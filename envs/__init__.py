"""Coexistence environments: PettingZoo worlds plus the domain descriptions (`envs.base.Domain`)
that the trainer and the inference service need and PettingZoo lacks."""
