"""What the paper suite runs: scenarios, methods, episode counts, seeds (paper §4.2).

| scenario          | ego  | partners       | episodes (full / `--fast`)   | paper        |
|-------------------|------|----------------|------------------------------|--------------|
| `aligned`         | `c`  | `c4`           | 200 / 6                      | Fig. 5 left  |
| `non_aligned`     | `a2` | `b3`           | 200 / 6                      | Fig. 5 right |
| `five_agents`     | `a2` | `a0 b2 c4 e1`  | 100 / 4                      | Fig. 7       |
| `pair:{e}+{p}#r`  | goal pairs drawn per strict class (`envs.particle.scenarios`)  | 20 / 3 per pair | (ours) |
| `set:{goals}#r`   | five-agent goal sets drawn from the whole catalogue | 100 / 3 per set | (ours) |

Goal pairs nobody tuned on. Each of `replicates` replicates r = 0, 1, ... has its own seed
`seed + r`, and with it draws its own pairs from each strict class (`aligned_pairs`,
`non_aligned_pairs`, `mixed_pairs`; a count at least the class's size takes the whole class),
its own five-agent goal sets (`five_agent_sets`) and its own start states. The analysis pools a
pair's episodes over the replicates that drew it (`evaluation.paper.pairs`).

Choices the paper leaves open (or that the 2-core budget forces):

- Episodes end when every agent is inside its target at the same step (the env's termination)
  or after `max_steps` = 400 steps (the paper: 1000). Returns are sums of negative distances, so
  they depend on this limit wherever an episode does not terminate (e.g. NAIL in the
  non-aligned scenario): compare methods at one limit, not numbers across limits.
- Start states: `envs.particle.scenarios.start_states(start_seed, episodes, N)`; every method of a
  scenario faces the same starts (paired episodes). `start_seed = 1000 * seed + k` with k = 1, 2,
  3 for the three named scenarios and 100 + i for sampled pair i.
- Start seeds of replicate r (seed s = `seed` + r, base = 1000 s): base + 100 + i for its i-th
  pair (aligned, then non-aligned, then mixed) and base + 600 + k for its k-th goal set. Pairs
  of class c are `sample_pairs_of_class(base + 7 + c, ...)`, goal sets
  `sample_goal_sets(base + 11, ...)`.
- Partners act with the task networks of a separately trained population (`partner_alias`,
  default `partners`, trained with another seed), never with the ego's own networks; the
  controlled agent (agent 0) uses the `alias` population (default `production`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

from envs.particle.scenarios import (
    ALIGNED_PAIR,
    FIVE_AGENTS,
    NON_ALIGNED_PAIR,
    PAIR_CLASSES,
    PairClass,
    pair_class,
    room_to_help,
    sample_goal_sets,
    sample_pairs_of_class,
)
from services.engine import Method

PAPER_METHODS: tuple[Method, ...] = ("sl", "nail", "aail", "aail_bounded", "jl")
METHOD_LABELS: dict[str, str] = {
    "sl": "SL",
    "nail": "NAIL",
    "aail": "AAIL",
    "aail_bounded": "AAIL-B",
    "aail_budget": "AAIL-budget",
    "jl": "JL",
}
FIVE_AGENT_SET_SIZE = 5


@dataclass(frozen=True)
class Scenario:
    """One goal combination evaluated over `episodes` paired episodes."""

    name: str
    ego_goal: str
    partner_goals: tuple[str, ...]
    episodes: int
    start_seed: int
    replicate: int = 0

    @property
    def goals(self) -> tuple[str, ...]:
        return (self.ego_goal, *self.partner_goals)

    @property
    def n_agents(self) -> int:
        return 1 + len(self.partner_goals)

    @property
    def pair_class(self) -> PairClass | None:
        """For two agents: the pair's strict class (`envs.particle.scenarios.pair_class`)."""
        if len(self.partner_goals) != 1:
            return None
        return pair_class(self.ego_goal, self.partner_goals[0])

    @property
    def room_to_help(self) -> bool:
        """An aligned pair whose target strictly contains the partner's influence area."""
        return len(self.partner_goals) == 1 and room_to_help(self.ego_goal, self.partner_goals[0])

    @property
    def combo(self) -> str:
        return "+".join(self.goals)


@dataclass(frozen=True)
class SuiteConfig:
    """Settings of one run of the paper suite (see the module docstring)."""

    ENV: ClassVar[str] = "particle"
    """The environment: the paper suite's scenarios are the particle world's, not a setting."""

    episodes: int = 200
    five_agent_episodes: int = 100
    replicates: int = 3
    aligned_pairs: int = 85
    non_aligned_pairs: int = 40
    mixed_pairs: int = 20
    pair_episodes: int = 20
    five_agent_sets: int = 8
    set_episodes: int = 100
    max_steps: int = 400
    seed: int = 0
    methods: tuple[Method, ...] = PAPER_METHODS
    regret_bound: float | None = None  # aail_bounded's ε (None: the engine's default)
    alias: str = "production"
    partner_alias: str = "partners"
    fast: bool = False

    def __post_init__(self) -> None:
        for name in (
            "episodes",
            "five_agent_episodes",
            "pair_episodes",
            "set_episodes",
            "max_steps",
            "replicates",
        ):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}: expected >= 1, got {getattr(self, name)}")
        for name in ("aligned_pairs", "non_aligned_pairs", "mixed_pairs", "five_agent_sets"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name}: expected >= 0, got {getattr(self, name)}")
        if self.seed < 0:
            raise ValueError(f"seed: expected >= 0, got {self.seed}")
        if self.regret_bound is not None and not 0 <= self.regret_bound < float("inf"):
            raise ValueError(
                f"regret_bound: expected a finite number >= 0, got {self.regret_bound}"
            )
        missing = {"sl", "nail", "aail"} - set(self.methods)
        if missing:
            raise ValueError(
                f"methods: the paper's claims need SL, NAIL and AAIL; missing {missing}"
            )
        unknown = set(self.methods) - set(PAPER_METHODS)
        if unknown:
            raise ValueError(
                f"methods: unknown {sorted(unknown)}, expected some of {PAPER_METHODS}"
            )


FAST = SuiteConfig(
    episodes=6,
    five_agent_episodes=4,
    replicates=1,
    aligned_pairs=2,
    non_aligned_pairs=2,
    mixed_pairs=1,
    pair_episodes=3,
    five_agent_sets=1,
    set_episodes=3,
    max_steps=40,
    fast=True,
)


def fast_config(**overrides: object) -> SuiteConfig:
    """The `--fast` settings (a few short episodes), with overrides."""
    return replace(FAST, **overrides)  # type: ignore[arg-type]


def paper_scenarios(config: SuiteConfig) -> list[Scenario]:
    """The paper's three hand-picked scenarios (Figs. 5 and 7)."""
    base = 1000 * config.seed
    ego, partner = ALIGNED_PAIR
    aligned = Scenario("aligned", ego, (partner,), config.episodes, base + 1)
    ego, partner = NON_ALIGNED_PAIR
    non_aligned = Scenario("non_aligned", ego, (partner,), config.episodes, base + 2)
    ego, partners = FIVE_AGENTS
    five = Scenario("five_agents", ego, tuple(partners), config.five_agent_episodes, base + 3)
    return [aligned, non_aligned, five]


def pair_scenarios(config: SuiteConfig) -> list[Scenario]:
    """Every replicate's goal pairs, drawn per strict class (module docstring)."""
    counts = {
        "aligned": config.aligned_pairs,
        "non_aligned": config.non_aligned_pairs,
        "mixed": config.mixed_pairs,
    }
    scenarios = []
    for r in range(config.replicates):
        base = 1000 * (config.seed + r)
        drawn = [
            pair
            for c, kind in enumerate(PAIR_CLASSES)
            for pair in sample_pairs_of_class(base + 7 + c, kind, counts[kind])
        ]
        scenarios += [
            Scenario(
                f"pair:{ego}+{partner}#{r}",
                ego,
                (partner,),
                config.pair_episodes,
                base + 100 + i,
                r,
            )
            for i, (ego, partner) in enumerate(drawn)
        ]
    return scenarios


def goal_set_scenarios(config: SuiteConfig) -> list[Scenario]:
    """Every replicate's five-agent goal sets, drawn from the whole catalogue."""
    scenarios = []
    for r in range(config.replicates):
        base = 1000 * (config.seed + r)
        sets = sample_goal_sets(base + 11, config.five_agent_sets, FIVE_AGENT_SET_SIZE)
        scenarios += [
            Scenario(
                f"set:{'+'.join(goals)}#{r}",
                goals[0],
                goals[1:],
                config.set_episodes,
                base + 600 + k,
                r,
            )
            for k, goals in enumerate(sets)
        ]
    return scenarios
