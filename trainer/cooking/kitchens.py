"""Training kitchens: where each recipe's networks learn, the scripted other cook, and restarts.

Every recipe has a *training kitchen* (`TRAINING_KITCHENS`): a layout, the seat of the cook who
cooks the recipe (the *focal* cook) and what the other cook does. The Fig. 8 recipes train in the
coexistence layout itself, so the networks know the kitchen they are evaluated in:

| recipe               | layout        | focal seat | other cook (scripted)                           |
|----------------------|---------------|------------|-------------------------------------------------|
| `TomatoLettuceSalad` | `coexistence` | 0 (left)   | cooks CarrotBanana (gets stuck: no carrot)      |
| `ChoppedTomato`      | `coexistence` | 0 (left)   | cooks CarrotBanana                              |
| `CarrotBanana`       | `coexistence` | 1 (right)  | cooks TomatoLettuceSalad and hands the carrot   |
|                      |               |            | over the pass-through counter: first, from a    |
|                      |               |            | random step in 0..`handover_delay_max` on       |
|                      |               |            | (`handover_first_prob`), else after its dish    |
| `OnionSoup`          | `open`        | 0          | cooks TomatoLettuceSalad                        |
| `BananaSmoothie`     | `open`        | 0          | cooks CarrotBanana                              |

The random hand-over step makes the carrot's arrival vary independently of the helper's own
progress, so the CarrotBanana network's value learns that the carrot is coming (the impact reward
of eq. 6 is built from that value). Episodes in which the helper serves its salad first hold the
states a helping AAIL cook creates (paper §4.4: the carrot comes after the own dish); the impact
learner starts from them (`CookingImpactConfig.handover_first_prob`). The scripted other cook
takes a random action with probability `partner_random_prob`, so its positions and timings vary.

Restarts. A kitchen restarts `episode_steps` after its start, or `linger_steps` after the focal
cook's dish. With probability `scripted_start_prob` it restarts from a *scripted start*: a state
drawn from a pool of episodes in which both cooks are scripted (recorded once, at construction),
otherwise from the layout's start (agents on random cells of their rooms with `random_starts`).
Scripted starts are a start-state curriculum (resetting to states of a demonstration, as in
learning Montezuma's Revenge from one demonstration): a dish 20-50 steps away is rarely found by
Boltzmann exploration from scratch, but from a state a few steps before it, it is; the value then
propagates back to the earlier states. Only the learner's own actions are stored for learning.
Gates and evaluation always start plainly.

The recorded episodes cover more than one way to cook: the focal cook first wanders for 0 to
`pool_idle_max` steps (random actions), and in a share `pool_other_order_prob` of them it waits
for the handed-over ingredient and prepares it first (`ScriptedCook(first=...)`). A learner that
waits for the carrot then finds the rest of the recipe demonstrated from there. The training
reward also charges `spoil_penalty` per needed ingredient newly wasted on a plate
(`trainer.cooking.shaping`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from envs.cooking import COOKING, DISH_REWARD, TIME_PENALTY, BatchedCookingWorld, ScriptedCook
from envs.cooking.recipes import recipe_index
from envs.cooking.world import CookingState, start_states
from trainer.cooking.config import CookingConfig
from trainer.cooking.shaping import wasted_items


@dataclass(frozen=True)
class TrainingKitchen:
    layout: str
    seat: int  # the focal cook: the one who cooks the recipe
    other_recipe: str  # what the other cook cooks
    handover: str | None = None  # the other cook also hands this ingredient over


TRAINING_KITCHENS: dict[str, TrainingKitchen] = {
    "TomatoLettuceSalad": TrainingKitchen("coexistence", 0, "CarrotBanana"),
    "ChoppedTomato": TrainingKitchen("coexistence", 0, "CarrotBanana"),
    "CarrotBanana": TrainingKitchen("coexistence", 1, "TomatoLettuceSalad", handover="carrot"),
    "OnionSoup": TrainingKitchen("open", 0, "TomatoLettuceSalad"),
    "BananaSmoothie": TrainingKitchen("open", 0, "CarrotBanana"),
}


def training_kitchen(recipe: str) -> TrainingKitchen:
    recipe_index(recipe)  # a ValueError naming the recipe if unknown
    return TRAINING_KITCHENS[recipe]


class KitchenStep(NamedTuple):
    rewards_BN: np.ndarray  # shaped rewards (what the learners train on)
    unshaped_BN: np.ndarray  # +20 dish, -0.01 per waiting step (what is reported)
    next_obs_BND: np.ndarray  # the true next observations (before any restart)
    done_B: np.ndarray  # kitchens that restarted after this step


class Kitchens:
    """E copies of one recipe's training kitchen, with the scripted other cook and restarts."""

    def __init__(
        self,
        recipe: str,
        n_envs: int,
        config: CookingConfig,
        seed: int,
        *,
        auto_reset: bool = True,
        scripted_starts: bool = True,
    ) -> None:
        self.recipe, self.kitchen = recipe, training_kitchen(recipe)
        self.focal, self.other = self.kitchen.seat, 1 - self.kitchen.seat
        self.config, self.auto_reset, self.n_envs = config, auto_reset, n_envs
        recipes_BN = np.empty((n_envs, 2), dtype=object)
        recipes_BN[:, self.focal], recipes_BN[:, self.other] = recipe, self.kitchen.other_recipe
        self.recipes_BN = recipes_BN.astype(str)
        # The step counter and restarts are kept here (the world's own never truncate).
        self.world = BatchedCookingWorld(
            self.kitchen.layout,
            self.recipes_BN,
            max_steps=1 << 30,
            sub_goal_reward=config.sub_goal_reward,
        )
        self.rng = np.random.default_rng(seed)
        self._plain = ScriptedCook(self.kitchen.other_recipe)
        self._helper_first, self._helper_after = (
            ScriptedCook(
                self.kitchen.other_recipe,
                handover=self.kitchen.handover,
                partner=self.focal,
                handover_first=first,
            )
            for first in (True, False)
        )
        self.steps_B = np.zeros(n_envs, dtype=np.int64)
        self.delay_B = np.zeros(n_envs, dtype=np.int64)  # hand-over step; -1: after its dish
        self.served_at_B = np.full(n_envs, -1)
        use_pool = scripted_starts and config.scripted_start_prob > 0
        self.pool = _scripted_pool(self, config) if use_pool else None
        self.obs_BND = self._restart(np.ones(n_envs, dtype=bool))

    def start_from(self, state: CookingState) -> None:
        """Put every kitchen into `state` (B = E kitchens) as a fresh episode (tests, demos)."""
        self.obs_BND = self.world.reset(state)
        self.steps_B[:] = 0
        self.served_at_B[:] = -1

    def views(self, seat: int) -> np.ndarray:
        """(E, 188) pair view of the cook at `seat` (with two agents: its own observation)."""
        return COOKING.task_views(self.obs_BND[:, seat], 2)[:, 0]

    def scripted_other(self, random_prob: float) -> np.ndarray:
        """Actions (E,) of the scripted other cook (table in the module docstring)."""
        state, layout = self.world.state, self.world.layout
        helps = self.kitchen.handover is not None
        actions_B = np.zeros(self.n_envs, dtype=np.int64)
        for b in range(self.n_envs):
            cook = self._plain
            if helps and self.delay_B[b] < 0:
                cook = self._helper_after
            elif helps and self.steps_B[b] >= self.delay_B[b]:
                cook = self._helper_first
            actions_B[b] = cook.act(layout, state, b, self.other, blocked=None)
        explore_B = self.rng.random(self.n_envs) < random_prob
        return np.where(explore_B, self.rng.integers(0, COOKING.n_actions, self.n_envs), actions_B)

    def scripted_focal(self, other_order_B: np.ndarray | None = None) -> np.ndarray:
        """Actions (E,) of the scripted cook of the recipe at the focal seat (gate reference);
        in the kitchens of `other_order_B` it prepares the handed-over ingredient first."""
        state, cook = self.world.state, ScriptedCook(self.recipe)
        waiter = ScriptedCook(self.recipe, first=self.kitchen.handover)
        cooks = [
            waiter if other_order_B is not None and other_order_B[b] else cook
            for b in range(self.n_envs)
        ]
        layout = self.world.layout
        return np.array([c.act(layout, state, b, self.focal, None) for b, c in enumerate(cooks)])

    def step(self, actions_BN: np.ndarray) -> KitchenStep:
        """Step every kitchen, then restart the finished ones (when `auto_reset`)."""
        before = self.world.state
        waiting_BN = ~before.delivered
        result = self.world.step(actions_BN)
        self.steps_B += 1
        after = self.world.state
        served_BN = after.delivered & waiting_BN
        unshaped_BN = DISH_REWARD * served_BN - TIME_PENALTY * waiting_BN
        rewards_BN = result.rewards_BN - self._penalties(before, after, actions_BN) * waiting_BN
        first_B = served_BN[:, self.focal]
        self.served_at_B[first_B] = self.steps_B[first_B]
        served_B = self.served_at_B >= 0
        lingered_B = served_B & (self.steps_B - self.served_at_B >= self.config.linger_steps)
        done_B = ((self.steps_B >= self.config.episode_steps) | lingered_B) & self.auto_reset
        self.obs_BND = self._restart(done_B) if done_B.any() else result.next_obs_BND
        return KitchenStep(rewards_BN, unshaped_BN, result.next_obs_BND, done_B)

    def _penalties(
        self, before: CookingState, after: CookingState, actions_BN: np.ndarray
    ) -> np.ndarray:
        """(E, 2) training penalties of the step: `spoil_penalty` per newly wasted ingredient
        (`trainer.cooking.shaping`)."""
        if not self.config.spoil_penalty:
            return np.zeros(np.shape(actions_BN))
        layout, recipes_BN = self.world.layout, self.world.recipes
        wasted_BN = wasted_items(layout, after, recipes_BN)
        new_BN = np.maximum(wasted_BN - wasted_items(layout, before, recipes_BN), 0)
        return self.config.spoil_penalty * new_BN

    def _restart(self, mask_B: np.ndarray) -> np.ndarray:
        """Restart the masked kitchens (module docstring); returns the new observations."""
        n_new = int(mask_B.sum())
        layout = self.world.layout
        fresh = start_states(layout, n_new, self.rng if self.config.random_starts else None)
        delay_N = self._draw_delays(n_new)
        if self.pool is not None:
            from_pool_N = self.rng.random(n_new) < self.config.scripted_start_prob
            picks = self.rng.integers(0, len(self.pool.steps_P), int(from_pool_N.sum()))
            for field, pooled in zip(fresh, self.pool.states, strict=True):
                field[from_pool_N] = pooled[picks]
            # the helper goes on as in the recorded episode: its hand-over step, shifted
            pooled_N = self.pool.delays_P[picks]
            shifted_N = np.maximum(pooled_N - self.pool.steps_P[picks], 0)
            delay_N[from_pool_N] = np.where(pooled_N < 0, -1, shifted_N)
        state = self.world.state
        for mine, new in zip(state, fresh, strict=True):
            mine[mask_B] = new
        # `reset` re-baselines every kitchen's sub-goals at its current progress: unchanged for
        # the running ones unless a plate was spoiled since (then a re-plating earns again).
        obs_BND = self.world.reset(state)
        self.steps_B[mask_B] = 0
        self.served_at_B[mask_B] = -1
        self.delay_B[mask_B] = delay_N
        return obs_BND

    def _draw_delays(self, n: int) -> np.ndarray:
        """Hand-over steps of n new episodes: -1 (after its own dish) or 0..handover_delay_max."""
        delays_N = self.rng.integers(0, self.config.handover_delay_max + 1, n)
        first_N = self.rng.random(n) < self.config.handover_first_prob
        return np.where(first_N, delays_N, -1)


class _Pool(NamedTuple):
    states: CookingState  # P recorded states, stacked on the batch axis
    steps_P: np.ndarray  # the step of its episode each state was recorded at
    delays_P: np.ndarray  # that episode's hand-over step (-1: after the helper's dish)


def _scripted_pool(kitchens: Kitchens, config: CookingConfig) -> _Pool:
    """Record `pool_episodes` x `pool_steps` states of both cooks scripted (module docstring).
    States after the focal cook's dish are left out (the learner meets those by lingering)."""
    recorder = Kitchens(
        kitchens.recipe,
        config.pool_episodes,
        config,
        int(kitchens.rng.integers(1 << 31)),
        auto_reset=False,
        scripted_starts=False,
    )
    states, steps, delays = [], [], []
    n_pool = config.pool_episodes
    rng = recorder.rng
    idle_E = rng.integers(0, config.pool_idle_max + 1, n_pool) if config.pool_idle_max else None
    other_order_E = None
    if config.pool_other_order_prob > 0 and kitchens.kitchen.handover is not None:
        other_order_E = rng.random(n_pool) < config.pool_other_order_prob
    for t in range(config.pool_steps):
        keep_E = ~recorder.world.state.delivered[:, recorder.focal]
        if not keep_E.any():
            break
        states.append(recorder.world.state.select(np.flatnonzero(keep_E)))
        steps.append(np.full(int(keep_E.sum()), t))
        delays.append(recorder.delay_B[keep_E])
        actions_BN = np.zeros((n_pool, 2), dtype=np.int64)
        focal_E = recorder.scripted_focal(other_order_E)
        if idle_E is not None:
            wander_E = rng.integers(0, COOKING.n_actions, n_pool)
            focal_E = np.where(t < idle_E, wander_E, focal_E)
        actions_BN[:, recorder.focal] = focal_E
        actions_BN[:, recorder.other] = recorder.scripted_other(config.partner_random_prob)
        recorder.step(actions_BN)
    stacked = CookingState(*(np.concatenate(f) for f in zip(*states, strict=True)))
    return _Pool(stacked, np.concatenate(steps), np.concatenate(delays))
