"""Quality gates for cooking networks: is a trained network good enough to be served?

Both gates run `eval_episodes` kitchens of the recipe's training kitchen
(`trainer.cooking.kitchens`) for `eval_steps` steps from plain starts (random cells of the rooms
with `random_starts`; never scripted starts), the other cook scripted as in training. Every run
of a gate uses the same seed, so its runs share starts and hand-over steps.

Task gate (recipe g): the *dish completion rate* of the network, its actions sampled from the
Boltzmann policy at the training α (what the server returns), must be at least
`completion_ratio` x the scripted cook's rate on the same kitchens (and above 0). Steps to the
dish and the unshaped return (+20 dish, -0.01 per waiting step) are reported beside it.

Impact gate (partner recipe h): the partner cooks h with its frozen task network, the ego acts
with the impact network (sampled at α) or rests (action 0). The impact network must do no harm:
the partner's completion rate beside it may be at most `no_harm_slack` below the rate beside a
resting ego; and where the partner cannot cook without it (fewer than `min_help_rate` of its
dishes beside a resting ego: CarrotBanana's carrot is in the other room) it must help, bringing
the partner to at least `min_help_rate`. Whether it helps is reported (`helps`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np
import torch

from envs.cooking import COOKING
from policy.qnet import StackedQNet
from policy.torch_ops import sample_boltzmann_t
from trainer.cooking.config import CookingConfig, CookingImpactConfig, CookingTaskConfig
from trainer.cooking.kitchens import Kitchens

# kitchens of every network -> actions (G, E, 2) of both seats
KitchenPolicy = Callable[[list[Kitchens]], np.ndarray]


@dataclass(frozen=True)
class CookingTaskGate:
    goal: str
    completion_rate: float
    scripted_completion_rate: float
    mean_steps_to_dish: float | None  # over the episodes with a dish (None without any)
    scripted_mean_steps_to_dish: float | None
    mean_return: float  # unshaped
    passed: bool
    FAILURE_NOTE: ClassVar[str] = (
        "A cooking task network that failed its gate gets no `production` alias, and in the "
        "kitchen impact networks train only against `production` task networks (trainer.zoo): "
        "its goal gets no impact network until a task network passes (then `coexist train "
        "impact --env cooking`)."
    )

    def metrics(self) -> dict[str, Any]:
        return asdict(self)

    def summary_cells(self) -> list[str]:
        """Dish completion and steps to the dish, unshaped return, the scripted cook's."""
        return [
            f"{self.completion_rate:.0%} in {_st(self.mean_steps_to_dish)}",
            f"{self.mean_return:.2f} (own)",
            f"{self.scripted_completion_rate:.0%} in "
            f"{_st(self.scripted_mean_steps_to_dish)} (scripted)",
        ]


@dataclass(frozen=True)
class CookingImpactGate:
    goal: str
    partner_completion_rate: float
    partner_completion_rate_resting_ego: float
    partner_return: float
    partner_return_resting_ego: float
    helps: bool
    passed: bool
    FAILURE_NOTE: ClassVar[str] = ""

    def metrics(self) -> dict[str, Any]:
        return asdict(self)

    def summary_cells(self) -> list[str]:
        """The partner's dish completion and return beside this network, beside a resting ego."""
        return [
            f"{self.partner_completion_rate:.0%}",
            f"{self.partner_return:.2f} (partner)",
            f"{self.partner_completion_rate_resting_ego:.0%} (resting ego)",
        ]


@dataclass(frozen=True)
class EpisodeStats:
    """Per network g and kitchen e: the focal cook's dish, when, and its unshaped return."""

    served_GE: np.ndarray
    steps_GE: np.ndarray  # step of the dish, -1 without one
    return_GE: np.ndarray

    def completion(self, g: int) -> float:
        return float(self.served_GE[g].mean())

    def steps_to_dish(self, g: int) -> float | None:
        served = self.served_GE[g]
        return float(self.steps_GE[g, served].mean()) if served.any() else None


def run_gate_episodes(
    recipes: Sequence[str], config: CookingConfig, seed: int, policy: KitchenPolicy
) -> EpisodeStats:
    """One episode of `eval_steps` per kitchen, `eval_episodes` kitchens per recipe."""
    kitchens = [
        Kitchens(r, config.eval_episodes, config, seed + g, auto_reset=False, scripted_starts=False)
        for g, r in enumerate(recipes)
    ]
    shape = (len(recipes), config.eval_episodes)
    served_GE, steps_GE, return_GE = np.zeros(shape, bool), np.full(shape, -1), np.zeros(shape)
    for t in range(config.eval_steps):
        actions_GE2 = policy(kitchens)
        for g, k in enumerate(kitchens):
            out = k.step(actions_GE2[g])
            return_GE[g] += out.unshaped_BN[:, k.focal]
            first = k.world.state.delivered[:, k.focal] & ~served_GE[g]
            steps_GE[g, first] = t + 1
            served_GE[g] |= first
    return EpisodeStats(served_GE, steps_GE, return_GE)


def _sampled(
    nets: StackedQNet, views_GED: np.ndarray, alpha: float, gen: torch.Generator
) -> np.ndarray:
    with torch.no_grad():
        q_GEA = nets(torch.from_numpy(views_GED.astype(np.float32)))
    return sample_boltzmann_t(q_GEA, alpha, gen).numpy()


def _seated(kitchens: list[Kitchens], focal_GE: np.ndarray, other_GE: np.ndarray) -> np.ndarray:
    """Actions (G, E, 2) of both seats: in the kitchens of network g the focal cook plays
    focal_GE[g], the other cook other_GE[g]."""
    actions = np.zeros((*focal_GE.shape, 2), dtype=np.int64)
    for g, k in enumerate(kitchens):
        actions[g, :, k.focal], actions[g, :, k.other] = focal_GE[g], other_GE[g]
    return actions


def cooking_task_gates(
    nets: StackedQNet, recipes: Sequence[str], config: CookingTaskConfig, seed: int
) -> list[CookingTaskGate]:
    """Gate G task networks (member g cooks recipes[g]) against the scripted cook."""
    generator = torch.Generator().manual_seed(seed)

    def policy(learned: bool) -> KitchenPolicy:
        def act(kitchens: list[Kitchens]) -> np.ndarray:
            if learned:
                views = np.stack([k.views(k.focal) for k in kitchens])
                focal_GE = _sampled(nets, views, config.alpha, generator)
            else:
                focal_GE = np.stack([k.scripted_focal() for k in kitchens])
            others = np.stack([k.scripted_other(config.partner_random_prob) for k in kitchens])
            return _seated(kitchens, focal_GE, others)

        return act

    mine = run_gate_episodes(recipes, config, seed, policy(True))
    ref = run_gate_episodes(recipes, config, seed, policy(False))
    gates = []
    for g, recipe in enumerate(recipes):
        rate, ref_rate = mine.completion(g), ref.completion(g)
        gates.append(
            CookingTaskGate(
                goal=recipe,
                completion_rate=rate,
                scripted_completion_rate=ref_rate,
                mean_steps_to_dish=mine.steps_to_dish(g),
                scripted_mean_steps_to_dish=ref.steps_to_dish(g),
                mean_return=float(mine.return_GE[g].mean()),
                passed=bool(rate > 0 and rate >= config.completion_ratio * ref_rate),
            )
        )
    return gates


def cooking_impact_gates(
    impact_nets: StackedQNet,
    partner_task_nets: StackedQNet,
    partner_recipes: Sequence[str],
    config: CookingImpactConfig,
    seed: int,
) -> list[CookingImpactGate]:
    """Does each impact network let its partner cook at least as well as a resting ego?"""

    def policy(ego_acts: bool) -> KitchenPolicy:
        # one stream per cook: the partner draws the same numbers beside either ego
        partner_gen = torch.Generator().manual_seed(seed)
        ego_gen = torch.Generator().manual_seed(seed + 1)

        def act(kitchens: list[Kitchens]) -> np.ndarray:
            ego_obs = [k.obs_BND[:, k.other] for k in kitchens]
            partner_views = np.stack([COOKING.partner_view(o, 2, 1) for o in ego_obs])
            partner_GE = _sampled(partner_task_nets, partner_views, config.alpha, partner_gen)
            ego_GE = np.zeros_like(partner_GE)
            if ego_acts:
                impact_views = np.stack([COOKING.impact_view(o, 2, 1) for o in ego_obs])
                ego_GE = _sampled(impact_nets, impact_views, config.alpha, ego_gen)
            return _seated(kitchens, partner_GE, ego_GE)

        return act

    helped = run_gate_episodes(partner_recipes, config, seed, policy(True))
    resting = run_gate_episodes(partner_recipes, config, seed, policy(False))
    gates = []
    for g, recipe in enumerate(partner_recipes):
        rate, idle_rate = helped.completion(g), resting.completion(g)
        gates.append(
            CookingImpactGate(
                goal=recipe,
                partner_completion_rate=rate,
                partner_completion_rate_resting_ego=idle_rate,
                partner_return=float(helped.return_GE[g].mean()),
                partner_return_resting_ego=float(resting.return_GE[g].mean()),
                helps=rate > idle_rate,
                passed=rate >= idle_rate - config.no_harm_slack
                and (idle_rate >= config.min_help_rate or rate >= config.min_help_rate),
            )
        )
    return gates


def print_cooking_gates(batches: Sequence[Any], console: Any = None) -> None:
    """A table of the cooking gates of `batches` (`TrainedBatch`es); nothing if there are none."""
    from rich.console import Console
    from rich.table import Table

    rows = [(b.kind, g) for b in batches for g in b.gates if g is not None]
    if not rows:
        return
    table = Table(title="cooking gates: dish completion")
    for col in ("network", "gate", "completion", "reference", "steps to dish / partner return"):
        table.add_column(col, justify="left" if col in ("network", "gate") else "right")
    for kind, gate in rows:
        verdict = "[green]passed[/green]" if gate.passed else "[red]failed[/red]"
        if kind == "task":
            table.add_row(
                f"task {gate.goal}",
                verdict,
                f"{gate.completion_rate:.0%}",
                f"{gate.scripted_completion_rate:.0%} (scripted cook)",
                f"{_steps(gate.mean_steps_to_dish)} (scripted "
                f"{_steps(gate.scripted_mean_steps_to_dish)})",
            )
        else:
            table.add_row(
                f"impact {gate.goal}",
                verdict,
                f"{gate.partner_completion_rate:.0%} (partner)",
                f"{gate.partner_completion_rate_resting_ego:.0%} (resting ego)",
                f"{gate.partner_return:.2f} (resting ego {gate.partner_return_resting_ego:.2f})",
            )
    (console or Console()).print(table)


def _steps(steps: float | None) -> str:
    return "-" if steps is None else f"{steps:.1f}"


def _st(steps: float | None) -> str:
    return "-" if steps is None else f"{steps:.0f} st"
