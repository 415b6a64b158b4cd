"""envs.base: what every registered domain promises the engine beyond the types, checked on
each one: one task view per other agent (the engine reads partner p's impact view out of the
task views, `services.engine.planning.member_inputs`)."""

from __future__ import annotations

import numpy as np
import pytest

from envs.registry import get_domain, known_envs


@pytest.mark.parametrize("env", known_envs())
def test_one_task_view_per_other_agent(env: str) -> None:
    domain = get_domain(env)
    rng = np.random.default_rng(0)
    for n_agents in range(2, min(domain.max_agents, 5) + 1):
        obs_BD = rng.uniform(-1.0, 1.0, (3, domain.obs_dim(n_agents))).astype(np.float32)
        views_BKP = domain.task_views(obs_BD, n_agents)
        assert views_BKP.shape == (3, n_agents - 1, domain.pair_obs_dim)
