"""envs.base: what every registered domain promises the engine beyond the types, checked on
each one (the engine relies on it: `services.engine.engine._inputs` reads the impact views out
of the task views)."""

from __future__ import annotations

import numpy as np
import pytest

from envs.registry import get_domain, known_envs


@pytest.mark.parametrize("env", known_envs())
def test_a_partners_impact_view_is_its_task_view(env: str) -> None:
    domain = get_domain(env)
    rng = np.random.default_rng(0)
    for n_agents in range(2, min(domain.max_agents, 5) + 1):
        obs_BD = rng.uniform(-1.0, 1.0, (3, domain.obs_dim(n_agents))).astype(np.float32)
        views_BKP = domain.task_views(obs_BD, n_agents)
        assert views_BKP.shape == (3, n_agents - 1, domain.pair_obs_dim)
        for partner in range(1, n_agents):
            impact_BP = domain.impact_view(obs_BD, n_agents, partner)
            np.testing.assert_array_equal(impact_BP, views_BKP[:, partner - 1])
