"""MPE2 landmarks: agents of MPE2's particle physics (mpe2._mpe_utils.core: forces, damping,
soft contact between agents) each heading for its own landmark. Agents collide and push each
other, so an agent in a partner's way hinders it and one that steps aside helps: a coexistence
problem on a world from the PettingZoo ecosystem, registered with coexist by entry point."""
