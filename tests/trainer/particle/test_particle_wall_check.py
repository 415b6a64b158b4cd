"""The task gate's wall check (`trainer.particle.gates.wall_check`) fails a policy that stops
short of its target when the other agent rests in a corner, and passes one that does not."""

from __future__ import annotations

import numpy as np

from envs.particle.goals import goal_index
from envs.particle.scripted import scripted_actions
from trainer.particle.gates import wall_check


def _goals_BN(state_BN4: np.ndarray, goals: list[int]) -> np.ndarray:
    per_goal = state_BN4.shape[0] // len(goals)
    goal_B = np.repeat(np.asarray(goals), per_goal)
    return np.stack([goal_B, goal_B], axis=1)


def test_a_policy_that_heads_for_its_target_passes() -> None:
    goals = [goal_index("d3"), goal_index("a0")]

    def heads_for_target(state_BN4: np.ndarray, obs_BND: np.ndarray) -> np.ndarray:
        return scripted_actions(state_BN4, _goals_BN(state_BN4, goals))

    assert wall_check(goals, heads_for_target, steps=100).tolist() == [1.0, 1.0]


def test_a_policy_that_freezes_beside_a_partner_in_a_corner_fails() -> None:
    goals = [goal_index("d3")]

    def freezes(state_BN4: np.ndarray, obs_BND: np.ndarray) -> np.ndarray:
        actions_BN = scripted_actions(state_BN4, _goals_BN(state_BN4, goals))
        partner_xy_B2 = state_BN4[:, 1, :2]
        in_corner_B = np.all((partner_xy_B2 == 0.0) | (partner_xy_B2 == 1.0), axis=1)
        actions_BN[in_corner_B, 0] = 0  # rests for good: the d3 network's failure, made exact
        return actions_BN

    share = wall_check(goals, freezes, steps=100)
    # 4 of the 8 partner placements are corners; the starts inside d3's target still "reach"
    assert 0.5 <= share[0] < 1.0
