"""Coexistence environments: PettingZoo worlds plus the domain descriptions the trainer and server need."""
