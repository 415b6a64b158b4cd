"""What the learning agent sees and earns in the particle world, for each learner (paper §3.1-3.2).

| learner | world | learning agent's view | reward | the other agents |
|---|---|---|---|---|
| task (goal g) | 2 agents | task view (ego, partner) | the ego's own reward r_g | a partner heading for a random goal (scripted, 30 % random actions) |
| impact (partner goal h) | 2 agents | impact view (ego, partner) | I = V^h(s'_p) − V^h(s_p), eq. 6 | the partner acts with the frozen task net of h |
| joint (g, h1..hk) | 1+k agents | the ego's whole observation | Σ_i r_i over all agents | each partner acts with the frozen task net of its goal |

All rollouts share the episode bookkeeping in `EpisodeTracker`: training episodes are cut after
`episode_steps` (a time limit, bootstrapped through), then restart from uniform random states.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from envs.particle.batched import BatchedParticleWorld
from envs.particle.domain import PARTICLE
from envs.particle.goals import GOAL_IDS
from envs.particle.scripted import scripted_actions
from policy.qnet import StackedQNet
from trainer.config import SoftQConfig, TaskConfig
from trainer.frozen import FrozenTaskNets
from trainer.loop import EpisodeTracker

N_GOALS = len(GOAL_IDS)


def wall_states(rng: np.random.Generator, n: int) -> np.ndarray:
    """`n` resting states on the world's walls, (n, 4): a uniform point of a uniform side, or
    (with probability 1/3) a uniform corner; velocity zero."""
    states_N4 = np.zeros((n, 4))
    along_N, side_N = rng.random(n), rng.integers(0, 4, n)
    corner_N = rng.random(n) < 1 / 3
    along_N = np.where(corner_N, np.round(along_N), along_N)
    wall_N = (side_N % 2).astype(np.float64)  # sides 0, 1: x on the wall; 2, 3: y on the wall
    x_wall_N = side_N < 2
    states_N4[:, 0] = np.where(x_wall_N, wall_N, along_N)
    states_N4[:, 1] = np.where(x_wall_N, along_N, wall_N)
    return states_N4


class ParticleTaskRollout:
    """Ego (agent 0) learns goal g; agent 1 heads for a random goal so its position varies."""

    obs_dim = PARTICLE.pair_obs_dim
    n_actions = PARTICLE.n_actions

    def __init__(self, goals: Sequence[int], config: TaskConfig, seed: int) -> None:
        self.n_nets, self.envs_per_net = len(goals), config.envs_per_net
        self.config = config
        self.rng = np.random.default_rng(seed)
        n_envs = self.n_nets * self.envs_per_net
        self.goals_BN = np.stack(
            [
                np.repeat(np.asarray(goals), self.envs_per_net),
                self.rng.integers(0, N_GOALS, n_envs),
            ],
            axis=1,
        )
        self.world = BatchedParticleWorld(self.goals_BN, max_steps=config.episode_steps, seed=seed)
        self.world.reset()
        self.resting_B = np.zeros(n_envs, dtype=bool)
        self.obs_BND = self._rest_some_on_walls(np.ones(n_envs, dtype=bool))
        self.tracker = EpisodeTracker(self.n_nets, self.envs_per_net)

    def _rest_some_on_walls(self, fresh_B: np.ndarray) -> np.ndarray:
        """Of the freshly started worlds, `partner_wall_prob` get a partner resting on a wall
        (`TaskConfig.partner_wall_prob`); the observations after."""
        self.resting_B[fresh_B] = (
            self.rng.random(int(fresh_B.sum())) < self.config.partner_wall_prob
        )
        rows_B = fresh_B & self.resting_B
        return self.world.place(rows_B, 1, wall_states(self.rng, int(rows_B.sum())))

    def _views(self, obs_BND: np.ndarray) -> np.ndarray:
        views_B8 = PARTICLE.task_views(obs_BND[:, 0], 2)[:, 0]
        return views_B8.reshape(self.n_nets, self.envs_per_net, -1).astype(np.float32)

    def observe(self) -> np.ndarray:
        return self._views(self.obs_BND)

    def _partner_actions(self) -> np.ndarray:
        n_envs = self.goals_BN.shape[0]
        if self.config.partner_behaviour == "random":
            return np.asarray(self.rng.integers(0, PARTICLE.n_actions, n_envs))
        acts_B = scripted_actions(self.world.state, self.goals_BN)[:, 1]
        explore = self.rng.random(n_envs) < self.config.partner_random_prob
        acts_B = np.where(explore, self.rng.integers(0, PARTICLE.n_actions, n_envs), acts_B)
        return np.where(self.resting_B, 0, acts_B)  # action 0: rest

    def step(self, actions_GE: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        actions_BN = np.stack([actions_GE.reshape(-1), self._partner_actions()], axis=1)
        result = self.world.step(actions_BN)
        reward_B = result.rewards_BN[:, 0]
        next_view = self._views(result.next_obs_BND)
        done_B = self.world.steps >= self.world.max_steps  # time limit, whatever the state
        self.tracker.add(reward_B, done_B)
        if done_B.any():
            self.goals_BN[done_B, 1] = self.rng.integers(0, N_GOALS, int(done_B.sum()))
            self.world.set_goals(self.goals_BN)
            self.world.reset_where(done_B)
            self.obs_BND = self._rest_some_on_walls(done_B)
        else:
            self.obs_BND = result.next_obs_BND
        shape = (self.n_nets, self.envs_per_net)
        return reward_B.reshape(shape).astype(np.float32), next_view

    def finished_returns(self) -> list[list[float]]:
        return self.tracker.pop()


class ParticleImpactRollout:
    """Ego (agent 0) learns the impact on a partner of goal h who acts with its task network."""

    obs_dim = PARTICLE.pair_obs_dim
    n_actions = PARTICLE.n_actions

    def __init__(
        self,
        partner_goals: Sequence[int],
        partner_task_nets: StackedQNet,
        config: SoftQConfig,
        seed: int,
    ) -> None:
        self.n_nets, self.envs_per_net = len(partner_goals), config.envs_per_net
        n_envs = self.n_nets * self.envs_per_net
        partner_B = np.repeat(np.asarray(partner_goals), self.envs_per_net)
        # The ego has no task of its own here; its world goal only fills the slot (reward unused).
        self.goals_BN = np.stack([partner_B, partner_B], axis=1)
        self.world = BatchedParticleWorld(self.goals_BN, max_steps=config.episode_steps, seed=seed)
        self.obs_BND = self.world.reset()
        generator = torch.Generator().manual_seed(seed + 1)
        self.partners = FrozenTaskNets(partner_task_nets, config.alpha, generator)
        self.tracker = EpisodeTracker(self.n_nets, self.envs_per_net)
        self.partner_return_tracker = EpisodeTracker(self.n_nets, self.envs_per_net)
        assert n_envs == self.goals_BN.shape[0]

    def _grouped(self, views_BD: np.ndarray) -> np.ndarray:
        return views_BD.reshape(self.n_nets, self.envs_per_net, -1).astype(np.float32)

    def observe(self) -> np.ndarray:
        return self._grouped(PARTICLE.impact_view(self.obs_BND[:, 0], 2, 1))

    def step(self, actions_GE: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        partner_view = self._grouped(PARTICLE.partner_view(self.obs_BND[:, 0], 2, 1))
        actions_BN = np.stack(
            [actions_GE.reshape(-1), self.partners.act(partner_view).reshape(-1)], axis=1
        )
        result = self.world.step(actions_BN)
        ego_next_B = result.next_obs_BND[:, 0]
        next_partner_view = self._grouped(PARTICLE.partner_view(ego_next_B, 2, 1))
        # Eq. 6: the impact is the change of the partner's soft value, on the partner's view.
        impact_GE = self.partners.soft_value(next_partner_view) - self.partners.soft_value(
            partner_view
        )
        done_B = self.world.steps >= self.world.max_steps  # time limit, whatever the state
        self.tracker.add(impact_GE.reshape(-1), done_B)
        self.partner_return_tracker.add(result.rewards_BN[:, 1], done_B)
        next_view = self._grouped(PARTICLE.impact_view(ego_next_B, 2, 1))
        self.obs_BND = self.world.reset_where(done_B) if done_B.any() else result.next_obs_BND
        return impact_GE.astype(np.float32), next_view

    def finished_returns(self) -> list[list[float]]:
        return self.tracker.pop()


class ParticleJointRollout:
    """Ego (agent 0) of a goal combination learns on the team reward Σ_i r_i (JL baseline)."""

    n_actions = PARTICLE.n_actions

    def __init__(
        self,
        combos: Sequence[Sequence[int]],
        partner_task_nets: Sequence[StackedQNet],
        config: SoftQConfig,
        seed: int,
    ) -> None:
        n_agents = {len(c) for c in combos}
        if len(n_agents) != 1:
            raise ValueError(
                f"combos: every combination needs the same agent count, got {n_agents}"
            )
        self.n_agents = n_agents.pop()
        self.obs_dim = PARTICLE.obs_dim(self.n_agents)
        self.n_nets, self.envs_per_net = len(combos), config.envs_per_net
        self.goals_BN = np.repeat(np.asarray(combos), self.envs_per_net, axis=0)
        self.world = BatchedParticleWorld(self.goals_BN, max_steps=config.episode_steps, seed=seed)
        self.obs_BND = self.world.reset()
        generator = torch.Generator().manual_seed(seed + 1)
        # partner_task_nets[k]: stacked task nets of the k-th partner's goal, one member per combo.
        self.partners = [FrozenTaskNets(n, config.alpha, generator) for n in partner_task_nets]
        self.tracker = EpisodeTracker(self.n_nets, self.envs_per_net)
        self._ended_B = np.zeros(len(self.goals_BN), dtype=bool)

    def observe(self) -> np.ndarray:
        obs = self.obs_BND[:, 0].reshape(self.n_nets, self.envs_per_net, -1)
        return obs.astype(np.float32)

    def step(self, actions_GE: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        columns = [actions_GE.reshape(-1)]
        for k, partner in enumerate(self.partners, start=1):
            # A partner's task net sees one (partner, other) pair per other agent, Q averaged:
            # the same rule the inference engine applies to the ego's task net.
            views_BKD = PARTICLE.task_views(self.obs_BND[:, k], self.n_agents)
            shape = (self.n_nets, self.envs_per_net, *views_BKD.shape[1:])
            columns.append(partner.act(views_BKD.reshape(shape)).reshape(-1))
        result = self.world.step(np.stack(columns, axis=1))
        team_B = result.rewards_BN.sum(axis=1)
        # The episode ends when every agent is inside its target at once, as the environment's
        # does (`envs.particle`) and as the evaluation scores it: the team's reward stops there.
        # Without the ending a JL learns another task: in a world that never ends, a non-aligned
        # partner keeps paying while the ego sits in its own target, and the team's best is for
        # the ego to give its target up.
        self._ended_B = result.terminated_B
        done_B = self._ended_B | (self.world.steps >= self.world.max_steps)
        self.tracker.add(team_B, done_B)
        next_obs = result.next_obs_BND[:, 0].reshape(self.n_nets, self.envs_per_net, -1)
        self.obs_BND = self.world.reset_where(done_B) if done_B.any() else result.next_obs_BND
        shape = (self.n_nets, self.envs_per_net)
        return team_B.reshape(shape).astype(np.float32), next_obs.astype(np.float32)

    def ended(self) -> np.ndarray:
        """(G, E): the transitions of the last step that ended their episode (`EndingRollout`)."""
        return self._ended_B.reshape(self.n_nets, self.envs_per_net)

    def finished_returns(self) -> list[list[float]]:
        return self.tracker.pop()
