"""Training configurations for the cooking world (paper §4.3-4.4): sparse dishes, long episodes.

The soft-Q algorithm is the particle world's (Algorithm 1, `trainer.loop`); what changes is the
reward's shape. A dish pays +20 once, after 20-50 scripted steps (`envs.cooking.scripted`), so:

| field               | cooking | particle | why                                                   |
|---------------------|---------|----------|-------------------------------------------------------|
| gamma               | 0.98    | 0.9      | dishes are 25-60 steps away: γ^50 = 0.36 still carries the +20 back to the start (0.9^50 = 0.005 does not); 0.99 doubles the entropy offset α log5 / (1-γ) in every V |
| alpha               | 0.05    | 0.02     | a wasted step costs ~20 γ^k (1 - γ²) ≈ 0.3-0.8 of Q: at α = 0.05 the policy is sharp on the way to a dish and near uniform where Q is still flat (exploration) |
| sub_goal_reward     | 1.0     | -        | shaping (the env's `sub_goal_reward`): +1 per recipe step done for the first time; curves and gates report the unshaped reward |
| scripted_start_prob | 0.5     | -        | half the restarts begin at a state of a scripted episode (start-state curriculum, `trainer.cooking.kitchens`). Without it: one sub-goal per ~300 steps, no dish in 4 000 batched steps. At 0.8 the salad learned in 20 000 steps but CarrotBanana failed from plain starts (it rarely saw the first steps) |
| pool_other_order_prob | 0.5   | -        | half the recorded CarrotBanana episodes chop the handed-over carrot first. The scripted cook always chopped the banana first, so a learner that waited for the carrot (many did) met "chopped carrot plated, banana raw" only by itself, and most failed runs then scooped the raw banana onto the plate |
| pool_idle_max       | 20      | -        | the recorded cook first wanders 0..20 steps: the pool holds late starts, like a learner's |
| spoil_penalty       | 2.0     | -        | -2 per needed ingredient newly on a plate that can never be served (`trainer.cooking.shaping`): the mistake that ended most failed CarrotBanana runs costs something at once |
| lr, target_every    | 1e-3, 100 | 3e-4, 250 | value must travel back ~50 steps: more frequent target copies and a larger step (3e-4 / 250 learned nothing in 4 000 steps) |
| batch_size          | 256     | 128      | dish transitions are rare in the replay                |
| envs_per_net        | 16      | 16       | the scripted other cook dominates the step time (`docs/performance.md`) |
| episode_steps       | 120     | 150      | the slowest dish (~60 steps) plus `linger_steps`       |
| total_steps         | 48 000  | 12 000   | with the three rows below, 5 of 5 CarrotBanana seeds passed by 48 000 (4 of them by 36 000); without them 8 of 16 (`reports/cooking/README.md`) |
| handover_delay_max  | 30      | -        | the helper's hand-over step; 60 left the CarrotBanana cook waiting most of the time |
| linger_steps        | 30 (task), 8 (impact) | - | a kitchen goes on after the learner's dish, so the task network sees post-dish states (its Q flattens there, which lets AAIL hand control to the impact network, eq. 9) |

No n-step returns: the shared loop stores one-step transitions (eq. 5); shaping and γ = 0.98
carry the signal instead. Episodes end by a time limit or `linger_steps` after the dish; both are
bootstrapped (the loop has no terminal mask), which is right here: the world goes on for the
partner after the learner's dish, and the learner keeps acting in it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

from trainer.config import SoftQConfig


@dataclass(frozen=True)
class CookingConfig(SoftQConfig):
    """Soft-Q hyperparameters and kitchen settings shared by the cooking learners."""

    ENV: ClassVar[str] = "cooking"

    gamma: float = 0.98
    """Discount factor γ (eq. 5); see the module table."""
    alpha: float = 0.05
    """Temperature α of the Boltzmann policy (eq. 2) and the soft value (eq. 3)."""
    lr: float = 1e-3
    """Adam learning rate."""
    target_every: int = 100
    """Hard copy of the online weights into the target network every this many updates."""
    envs_per_net: int = 16
    """Parallel kitchens per network."""
    warmup_steps: int = 100
    """Batched steps collected before the first update."""
    episode_steps: int = 120
    """Training episodes are cut after this many steps (bootstrapped)."""
    batch_size: int = 256
    """Minibatch size per network per update."""
    total_steps: int = 48_000
    """Batched environment steps per network."""
    sub_goal_reward: float = 1.0
    """Shaping reward per recipe step done for the first time (0 turns shaping off)."""
    spoil_penalty: float = 2.0
    """Shaping penalty per ingredient the learner's recipe needs that newly lies on a plate that
    can never be served (`trainer.cooking.shaping`); 0 turns it off."""
    linger_steps: int = 8
    """Steps a kitchen goes on after the learner's (or, for impact, the partner's) dish."""
    random_starts: bool = True
    """Start every agent on a random floor cell of its room (coverage); gates use them too."""
    partner_random_prob: float = 0.2
    """Share of random actions of a scripted partner (task training and gates)."""
    handover_delay_max: int = 30
    """A helper partner hands its ingredient over first from a step drawn from 0..this ..."""
    handover_first_prob: float = 1.0
    """... in this share of the episodes; in the others it serves its own dish first."""
    scripted_start_prob: float = 0.5
    """Share of restarts from a state of a scripted episode (start-state curriculum,
    `trainer.cooking.kitchens`); 0 turns it off."""
    pool_episodes: int = 32
    """Scripted episodes recorded for the pool of scripted starts."""
    pool_steps: int = 100
    """Steps recorded per scripted episode (states after the focal cook's dish are dropped)."""
    pool_other_order_prob: float = 0.5
    """Share of recorded episodes in which the focal cook waits for the ingredient the other
    cook hands over and prepares it first (`ScriptedCook(first=...)`): the other order of the
    recipe, and the states a learner that waited for the carrot is in."""
    pool_idle_max: int = 20
    """The focal cook of a recorded episode first wanders (random actions) for a number of
    steps drawn from 0..this, then cooks as scripted (`trainer.cooking.kitchens`)."""
    eval_episodes: int = 64
    """Episodes per network in the quality gate."""
    eval_steps: int = 200
    """Steps per gate episode."""


@dataclass(frozen=True)
class CookingTaskConfig(CookingConfig):
    """Task networks: one per recipe, on the learner's own (shaped) reward (paper §3.1)."""

    linger_steps: int = 30
    """Steps a kitchen goes on after the learner's dish. The true soft Q there is flat (no reward
    is left to earn), and AAIL relies on it: a flat task policy hands control to the impact
    network (eq. 9). With 8 steps the salad network stayed confident in post-dish states it had
    rarely seen (e.g. holding the carrot: "put it back", p = 1) and AAIL never handed the carrot
    over; the impact network alone, from the same states, did in 40 of 40 episodes."""
    completion_ratio: float = 0.8
    """Gate: the network's dish completion rate must be at least this share of the scripted
    cook's on the same kitchens (same starts, same partner)."""


@dataclass(frozen=True)
class CookingImpactConfig(CookingConfig):
    """Impact networks: one per partner recipe, by self-play (paper §3.2, eqs. 6-7)."""

    total_steps: int = 24_000
    """Batched environment steps per network. With 8 000 (and Boltzmann exploration alone) the
    retrained zoo's CarrotBanana network let its partner cook 20 % and 0 % of its dishes (two
    seeds) against 98 % for the zoo before: `reports/cooking/README.md`."""
    explore_eps: float = 0.3
    """Share of uniformly random actions while training (`trainer.config.SoftQConfig`): the
    hand-over is a long chain of actions that Boltzmann exploration at α alone rarely tries."""
    handover_first_prob: float = 0.5
    """Half the scripted starts come from episodes in which the helper (the learner's seat)
    serves its own dish before it hands the carrot over: the states an AAIL cook reaches after
    its dish (paper §4.4), which the impact network must know. (Task networks keep 1.0: with
    0.5 or 0.75 the CarrotBanana network failed its gate after 32 000-48 000 steps.)"""
    impact_reward: Literal["value_change", "value_change_plus_reward"] = "value_change_plus_reward"
    """`value_change`: eq. 6 as printed, I = V(s') - V(s). `value_change_plus_reward` adds the
    partner's reward of the step, I = r + V(s') - V(s): the change of the partner's expected
    *episode* return R = Σ_t r_t, the quantity eq. 6 is derived from. It matters in a sparse world:
    when the partner serves, V drops from ~20 to ~0 while r pays the 20, so eq. 6 as printed
    punishes the ego for the very dish it helped to cook."""
    no_harm_slack: float = 0.05
    """Gate: the partner's completion rate with the impact-driven ego may be at most this much
    below its rate beside a resting ego."""
    min_help_rate: float = 0.5
    """Gate: where the partner completes fewer than this share of its dishes beside a resting
    ego (it needs the ego: CarrotBanana's carrot is in the other room), the impact network must
    let it complete at least this share. "Does no harm" alone passed a network that handed the
    carrot over in one episode in five."""
