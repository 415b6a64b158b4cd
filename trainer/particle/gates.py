"""Quality gates: is a trained network good enough to be served (`production`)?

Task gate (per goal g), on `eval_episodes` seeded random starts, a partner heading for a random
goal with the scripted controller (deterministic, so every run below sees the same partner):
- success: share of episodes in which the ego reaches its target area, sampling its actions from
  the Boltzmann policy at the training α (what the server returns), must be ≥ `success_threshold`;
- return: the mean *own-target* return (−Σ_t distance to its target area: the part of the reward
  the ego's actions control; the influence part depends only on the partner, identical in every
  run) of the network's greedy policy must be within max(`return_margin` × |scripted|,
  `return_slack`) of the scripted straight-to-target controller's on the same starts. Greedy,
  because this compares what the network *learned* with a deterministic controller; sampling
  noise at α is measured by the success rate and reported (`sampled_own_target_return`).
- walls (`wall_check`): from a 6 × 6 grid of starts, with the other agent resting in each
  corner and at each wall's middle, the sampled policy must reach the target area within
  `eval_steps` in every episode (`wall_success_threshold`). A partner resting in a corner is
  rare among random starts but common among real partners (one heading for a corner cell); task
  networks that had not seen it stopped short of their target for whole episodes, and the
  random-start episodes above passed them.

Impact gate (per partner goal h), two checks that must both pass:
- helps: on seeded random starts the partner acts with its task network; the partner's mean
  return with the impact-driven ego must exceed its mean return with an ego that rests (action 0)
  on the same starts;
- directions (`trainer.particle.directions`): from states spread over the world, the network's
  preferred push must raise the partner's value where that value says a push helps, and no push
  it clearly needs may be dead. Episodes alone passed networks that never pushed left or down.

Joint gate (per goal combination: the JL baseline), on seeded random starts, every partner
acting with its own task network at α (as the JL trained beside them), episodes ending when
every agent is inside its target at once (the environment's ending), run twice on the same
starts: the JL network as the ego, then the ego's own task network (SL, what coexist serves
without partners). Sampled at α both, with the partners' actions drawn from one generator
seeded alike. Passed when the team return (Σ over agents), what the JL learns, is within
max(`return_margin` × |SL's|, `return_slack`) of SL's or above: a JL that does not earn the
team what SL earns it has not learned the team's reward. How often its ego reaches its own
target is reported beside SL's, not gated: where the partners gain more from the ego than it
loses, the team's reward pays the ego to give up its own target, and a JL that learned it does.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np
import torch

from envs.particle.batched import BatchedParticleWorld
from envs.particle.domain import PARTICLE
from envs.particle.goals import GOAL_IDS, TARGET_BOXES_G4
from envs.particle.scripted import scripted_actions
from envs.particle.world import box_distance, in_target, observations, random_states
from policy.qnet import StackedQNet
from policy.torch_ops import sample_boltzmann_t
from trainer.config import ImpactConfig, JointConfig, TaskConfig
from trainer.frozen import FrozenTaskNets
from trainer.particle.directions import dead_pushes, direction_checks

# (state_BN4, obs_BND) -> actions_BN
EgoPolicy = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class TaskGate:
    goal: str
    success_rate: float
    mean_return: float
    own_target_return: float
    scripted_own_target_return: float
    passed: bool
    sampled_own_target_return: float = float("nan")
    wall_success: float = float("nan")  # `wall_check`: share of its episodes that reach
    FAILURE_NOTE: ClassVar[str] = ""

    def metrics(self) -> dict[str, Any]:
        return asdict(self)

    def summary_cells(self) -> list[str]:
        """Success rate (and on the wall check), own-target return, the scripted controller's."""
        return [
            f"{self.success_rate:.0%}, walls {self.wall_success:.0%}",
            f"{self.own_target_return:.2f} (own target)",
            f"{self.scripted_own_target_return:.2f} (scripted)",
        ]


@dataclass(frozen=True)
class ImpactGate:
    goal: str
    partner_return: float
    partner_return_resting_ego: float
    passed: bool
    toward_share: float  # `trainer.particle.directions`
    push_recall: dict[str, float | None]
    dead_pushes: tuple[str, ...]  # pushes whose recall falls short
    FAILURE_NOTE: ClassVar[str] = ""

    def metrics(self) -> dict[str, Any]:
        return asdict(self)

    def summary_cells(self) -> list[str]:
        """Direction gate, the partner's return beside this network, beside a resting ego."""
        dead = f", dead: {'/'.join(self.dead_pushes)}" if self.dead_pushes else ""
        return [
            f"{self.toward_share:.0%} toward{dead}",
            f"{self.partner_return:.2f} (partner)",
            f"{self.partner_return_resting_ego:.2f} (resting ego)",
        ]


@dataclass(frozen=True)
class JointGate:
    goal: str  # the combination, "ego+partner+..."
    success_rate: float  # the JL ego reached its own target
    sl_success_rate: float  # the ego's own task network did, on the same starts
    team_return: float  # mean Σ over agents, JL ego
    sl_team_return: float
    passed: bool
    FAILURE_NOTE: ClassVar[str] = ""

    def metrics(self) -> dict[str, Any]:
        return asdict(self)

    def summary_cells(self) -> list[str]:
        """Success rate against SL's, team return, SL's team return."""
        return [
            f"{self.success_rate:.0%} (SL {self.sl_success_rate:.0%})",
            f"{self.team_return:.2f} (team)",
            f"{self.sl_team_return:.2f} (team, SL)",
        ]


def _grouped_q(nets: StackedQNet, views_BD: np.ndarray, n_nets: int) -> torch.Tensor:
    views = torch.from_numpy(views_BD.astype(np.float32)).reshape(n_nets, -1, views_BD.shape[-1])
    with torch.no_grad():
        return nets(views)


def _run(
    world: BatchedParticleWorld,
    goals_BN: np.ndarray,
    starts: np.ndarray,
    steps: int,
    policy: EgoPolicy,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per env: ego return, partner return, ego's own-target return, whether it reached its target."""
    world.reset(starts.copy())
    n_envs = starts.shape[0]
    returns_BN = np.zeros((n_envs, starts.shape[1]))
    own_B = np.zeros(n_envs)
    reached_B = np.zeros(n_envs, dtype=bool)
    target_B4 = TARGET_BOXES_G4[goals_BN[:, 0]]
    for _ in range(steps):
        result = world.step(policy(world.state, observations(world.state)))
        returns_BN += result.rewards_BN
        own_B -= box_distance(world.state[:, 0, :2], target_B4)
        reached_B |= in_target(world.state, goals_BN)[:, 0]
    return returns_BN[:, 0], returns_BN[:, 1], own_B, reached_B


WALL_GRID = 6  # starts per side of `wall_check`'s grid
WALL_PARTNER_XY = np.array(
    [(0, 0), (1, 0), (0, 1), (1, 1), (0.5, 0), (1, 0.5), (0.5, 1), (0, 0.5)], dtype=np.float64
)  # the corners and the walls' middles


def wall_check(goals: Sequence[int], policy: EgoPolicy, steps: int) -> np.ndarray:
    """Share of `wall_check` episodes (module docstring) in which the ego reaches its target,
    per goal, (G,). `policy` acts for the ego of G × 288 worlds (goal-major: the ego of goal g
    in rows g × 288 ...); the other agent rests whatever `policy` returns for it."""
    grid = np.linspace(0.05, 0.95, WALL_GRID)
    ego_S2 = np.array([(x, y) for x in grid for y in grid])
    n_eps = len(ego_S2) * len(WALL_PARTNER_XY)
    starts_E24 = np.zeros((n_eps, 2, 4))
    starts_E24[:, 0, :2] = np.repeat(ego_S2, len(WALL_PARTNER_XY), axis=0)
    starts_E24[:, 1, :2] = np.tile(WALL_PARTNER_XY, (len(ego_S2), 1))
    goal_B = np.repeat(np.asarray(goals), n_eps)
    goals_BN = np.stack([goal_B, goal_B], axis=1)  # the resting partner's goal does not matter
    world = BatchedParticleWorld(goals_BN, max_steps=steps + 1)
    world.reset(np.tile(starts_E24, (len(goals), 1, 1)))
    reached_B = np.zeros(len(goal_B), dtype=bool)
    for _ in range(steps):
        actions_BN = np.array(policy(world.state, observations(world.state)))
        actions_BN[:, 1] = 0  # the partner rests
        world.step(actions_BN)
        reached_B |= in_target(world.state, goals_BN)[:, 0]
    return reached_B.reshape(len(goals), n_eps).mean(axis=1)


def task_gates(
    nets: StackedQNet, goals: Sequence[int], config: TaskConfig, seed: int
) -> list[TaskGate]:
    """Evaluate G task networks (member g learned goals[g]) against the scripted controller."""
    n_nets, n_eps = len(goals), config.eval_episodes
    rng = np.random.default_rng(seed)
    goals_BN = np.stack(
        [np.repeat(np.asarray(goals), n_eps), rng.integers(0, len(GOAL_IDS), n_nets * n_eps)], 1
    )
    starts = random_states(rng, (n_nets * n_eps,), 2)
    world = BatchedParticleWorld(goals_BN, max_steps=config.eval_steps + 1, seed=seed)
    generator = torch.Generator().manual_seed(seed)

    def learned(greedy: bool) -> EgoPolicy:
        def policy(state_BN4: np.ndarray, obs_BND: np.ndarray) -> np.ndarray:
            q = _grouped_q(nets, PARTICLE.task_views(obs_BND[:, 0], 2)[:, 0], n_nets)
            acts = q.argmax(-1) if greedy else sample_boltzmann_t(q, config.alpha, generator)
            partner = scripted_actions(state_BN4, goals_BN)[:, 1]
            return np.stack([acts.numpy().reshape(-1), partner], axis=1)

        return policy

    def scripted(state_BN4: np.ndarray, obs_BND: np.ndarray) -> np.ndarray:
        return scripted_actions(state_BN4, goals_BN)

    def on_walls(state_BN4: np.ndarray, obs_BND: np.ndarray) -> np.ndarray:
        q = _grouped_q(nets, PARTICLE.task_views(obs_BND[:, 0], 2)[:, 0], n_nets)
        acts = sample_boltzmann_t(q, config.alpha, generator).numpy().reshape(-1)
        return np.stack([acts, np.zeros_like(acts)], axis=1)

    walls = wall_check(goals, on_walls, config.eval_steps)
    ret, _, sampled_own, reached = _run(world, goals_BN, starts, config.eval_steps, learned(False))
    _, _, own, _ = _run(world, goals_BN, starts, config.eval_steps, learned(True))
    _, _, ref, _ = _run(world, goals_BN, starts, config.eval_steps, scripted)
    gates = []
    for g, goal in enumerate(goals):
        part = slice(g * n_eps, (g + 1) * n_eps)
        success, own_mean, ref_mean = reached[part].mean(), own[part].mean(), ref[part].mean()
        allowed = max(config.return_margin * abs(ref_mean), config.return_slack)
        close_enough = own_mean >= ref_mean - allowed
        on_walls_ok = walls[g] >= config.wall_success_threshold
        passed = bool(success >= config.success_threshold and close_enough and on_walls_ok)
        gates.append(
            TaskGate(
                goal=GOAL_IDS[goal],
                success_rate=float(success),
                mean_return=float(ret[part].mean()),
                own_target_return=float(own_mean),
                scripted_own_target_return=float(ref_mean),
                passed=passed,
                sampled_own_target_return=float(sampled_own[part].mean()),
                wall_success=float(walls[g]),
            )
        )
    return gates


def impact_gates(
    impact_nets: StackedQNet,
    partner_task_nets: StackedQNet,
    partner_goals: Sequence[int],
    config: ImpactConfig,
    seed: int,
) -> list[ImpactGate]:
    """Does each impact network raise its partner's return over a resting ego, and push where
    the partner's value says it should (module docstring)?"""
    n_nets, n_eps = len(partner_goals), config.eval_episodes
    rng = np.random.default_rng(seed)
    partner_B = np.repeat(np.asarray(partner_goals), n_eps)
    goals_BN = np.stack([partner_B, partner_B], 1)
    world = BatchedParticleWorld(goals_BN, max_steps=config.eval_steps + 1, seed=seed)
    starts = random_states(rng, (n_nets * n_eps,), 2)

    def make_policy(ego_acts: bool) -> EgoPolicy:
        generator = torch.Generator().manual_seed(seed)

        def policy(state_BN4: np.ndarray, obs_BND: np.ndarray) -> np.ndarray:
            q_p = _grouped_q(partner_task_nets, PARTICLE.partner_view(obs_BND[:, 0], 2, 1), n_nets)
            partner = sample_boltzmann_t(q_p, config.alpha, generator).numpy().reshape(-1)
            if ego_acts:
                q_i = _grouped_q(impact_nets, PARTICLE.impact_view(obs_BND[:, 0], 2, 1), n_nets)
                ego = sample_boltzmann_t(q_i, config.alpha, generator).numpy().reshape(-1)
            else:
                ego = np.zeros_like(partner)
            return np.stack([ego, partner], axis=1)

        return policy

    _, with_impact, _, _ = _run(world, goals_BN, starts, config.eval_steps, make_policy(True))
    _, resting, _, _ = _run(world, goals_BN, starts, config.eval_steps, make_policy(False))
    directions = direction_checks(impact_nets, partner_task_nets, config, seed)
    gates = []
    for g, goal in enumerate(partner_goals):
        part = slice(g * n_eps, (g + 1) * n_eps)
        helped, idle = with_impact[part].mean(), resting[part].mean()
        check = directions[g]
        gates.append(
            ImpactGate(
                goal=GOAL_IDS[goal],
                partner_return=float(helped),
                partner_return_resting_ego=float(idle),
                passed=bool(helped > idle and check.passed),
                toward_share=check.toward_share,
                push_recall=check.push_recall,
                dead_pushes=tuple(dead_pushes(check, config)),
            )
        )
    return gates


def joint_gates(
    joint_nets: StackedQNet,
    combos: Sequence[Sequence[int]],
    ego_task_nets: StackedQNet,
    partner_task_nets: Sequence[StackedQNet],
    config: JointConfig,
    seed: int,
) -> list[JointGate]:
    """Does each JL network (member c learned combos[c]) earn its team what the ego's own task
    network (member c of `ego_task_nets`) earns it (module docstring)? `partner_task_nets[k]` stacks the task network of every combination's k-th
    partner, as the JL trained beside them."""
    n_combos, n_eps, n_agents = len(combos), config.eval_episodes, len(combos[0])
    rng = np.random.default_rng(seed)
    goals_BN = np.repeat(np.asarray(combos), n_eps, axis=0)
    starts = random_states(rng, (n_combos * n_eps,), n_agents)
    world = BatchedParticleWorld(goals_BN, max_steps=config.eval_steps + 1, seed=seed)

    def task_views(nets: FrozenTaskNets, obs_BD: np.ndarray) -> np.ndarray:
        views = PARTICLE.task_views(obs_BD, n_agents)  # (B, K, D): Q averaged over K, as served
        return nets.act(views.reshape(n_combos, n_eps, *views.shape[1:])).reshape(-1)

    def make_policy(joint: bool) -> EgoPolicy:
        generator = torch.Generator().manual_seed(seed)
        ego_generator = torch.Generator().manual_seed(seed + 1)
        partners = [FrozenTaskNets(n, config.alpha, generator) for n in partner_task_nets]
        own = FrozenTaskNets(ego_task_nets, config.alpha, ego_generator)

        def policy(state_BN4: np.ndarray, obs_BND: np.ndarray) -> np.ndarray:
            if joint:
                q = _grouped_q(joint_nets, obs_BND[:, 0], n_combos)
                ego = sample_boltzmann_t(q, config.alpha, ego_generator).numpy().reshape(-1)
            else:
                ego = task_views(own, obs_BND[:, 0])
            columns = [ego] + [task_views(p, obs_BND[:, k]) for k, p in enumerate(partners, 1)]
            return np.stack(columns, axis=1)

        return policy

    def run(joint: bool) -> tuple[np.ndarray, np.ndarray]:
        """Per episode: the team return and whether the ego reached its target. An episode ends
        when every agent is inside its target at once, as the environment's (and the JL's
        training episodes) do, or after `eval_steps`."""
        world.reset(starts.copy())
        policy = make_policy(joint)
        team_B = np.zeros(len(goals_BN))
        reached_B = np.zeros(len(goals_BN), dtype=bool)
        ended_B = np.zeros(len(goals_BN), dtype=bool)
        for _ in range(config.eval_steps):
            result = world.step(policy(world.state, observations(world.state)))
            team_B += np.where(ended_B, 0.0, result.rewards_BN.sum(axis=1))
            reached_B |= ~ended_B & in_target(world.state, goals_BN)[:, 0]
            ended_B |= result.terminated_B
        return team_B, reached_B

    team, reached = run(joint=True)
    sl_team, sl_reached = run(joint=False)
    gates = []
    for c, combo in enumerate(combos):
        part = slice(c * n_eps, (c + 1) * n_eps)
        success, sl_success = reached[part].mean(), sl_reached[part].mean()
        mean, sl_mean = team[part].mean(), sl_team[part].mean()
        allowed = max(config.return_margin * abs(sl_mean), config.return_slack)
        passed = mean >= sl_mean - allowed
        gates.append(
            JointGate(
                goal="+".join(GOAL_IDS[g] for g in combo),
                success_rate=float(success),
                sl_success_rate=float(sl_success),
                team_return=float(mean),
                sl_team_return=float(sl_mean),
                passed=bool(passed),
            )
        )
    return gates
