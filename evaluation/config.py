"""What the paper suite runs: scenarios, methods, episode counts, seeds (paper §4.2).

| scenario       | ego  | partners          | episodes (full / `--fast`) | paper       |
|----------------|------|-------------------|----------------------------|-------------|
| `aligned`      | `c`  | `c4`              | 200 / 6                    | Fig. 5 left |
| `non_aligned`  | `a2` | `b3`              | 200 / 6                    | Fig. 5 right|
| `five_agents`  | `a2` | `a0 b2 c4 e1`     | 100 / 4                    | Fig. 7      |
| `pair:{e}+{p}` | sampled from the 35 × 35 | | 20 per pair, 100 pairs / 3 per pair, 3 pairs | (ours) |

Choices the paper leaves open (or that the 2-core budget forces):

- Episodes end when every agent is inside its target at the same step (the env's termination)
  or after `max_steps` = 400 steps (the paper: 1000). Returns are sums of negative distances, so
  they depend on this limit wherever an episode does not terminate (e.g. NAIL in the
  non-aligned scenario): compare methods at one limit, not numbers across limits.
- Start states: `envs.particle.scenarios.start_states(start_seed, episodes, N)`; every method of a
  scenario faces the same starts (paired episodes). `start_seed = 1000 * seed + k` with k = 1, 2,
  3 for the three named scenarios and 100 + i for sampled pair i.
- Goal pairs: `sample_goal_pairs(1000 * seed + 7, pairs)`, each classified with `is_aligned`.
- Partners act with the task networks of a separately trained population (`partner_alias`,
  default `partners`, trained with another seed), never with the ego's own networks; the
  controlled agent (agent 0) uses the `alias` population (default `production`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from envs.particle.scenarios import (
    ALIGNED_PAIR,
    FIVE_AGENTS,
    NON_ALIGNED_PAIR,
    is_aligned,
    sample_goal_pairs,
)
from services.engine import Method

PAPER_METHODS: tuple[Method, ...] = ("sl", "nail", "aail", "jl")
METHOD_LABELS: dict[str, str] = {"sl": "SL", "nail": "NAIL", "aail": "AAIL", "jl": "JL"}


@dataclass(frozen=True)
class Scenario:
    """One goal combination evaluated over `episodes` paired episodes."""

    name: str
    ego_goal: str
    partner_goals: tuple[str, ...]
    episodes: int
    start_seed: int

    @property
    def goals(self) -> tuple[str, ...]:
        return (self.ego_goal, *self.partner_goals)

    @property
    def n_agents(self) -> int:
        return 1 + len(self.partner_goals)

    @property
    def aligned(self) -> bool | None:
        """For two agents: whether the ego's target overlaps the partner's influence area."""
        if len(self.partner_goals) != 1:
            return None
        return is_aligned(self.ego_goal, self.partner_goals[0])

    @property
    def combo(self) -> str:
        return "+".join(self.goals)


@dataclass(frozen=True)
class SuiteConfig:
    """Settings of one run of the paper suite (see the module docstring)."""

    episodes: int = 200
    five_agent_episodes: int = 100
    pairs: int = 100
    pair_episodes: int = 20
    max_steps: int = 400
    seed: int = 0
    methods: tuple[Method, ...] = PAPER_METHODS
    alias: str = "production"
    partner_alias: str = "partners"
    env: str = "particle"
    fast: bool = False

    def __post_init__(self) -> None:
        for name in ("episodes", "five_agent_episodes", "pair_episodes", "max_steps"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}: expected >= 1, got {getattr(self, name)}")
        if self.pairs < 0:
            raise ValueError(f"pairs: expected >= 0, got {self.pairs}")
        if self.seed < 0:
            raise ValueError(f"seed: expected >= 0, got {self.seed}")
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
        if self.env != "particle":
            raise ValueError(f"env: the paper suite runs on 'particle', got {self.env!r}")


FAST = SuiteConfig(
    episodes=6, five_agent_episodes=4, pairs=3, pair_episodes=3, max_steps=40, fast=True
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
    """`config.pairs` goal pairs sampled from the 35 × 35 combinations."""
    if config.pairs == 0:
        return []
    base = 1000 * config.seed
    triples = sample_goal_pairs(base + 7, config.pairs)
    return [
        Scenario(f"pair:{ego}+{partner}", ego, (partner,), config.pair_episodes, base + 100 + i)
        for i, (ego, partner, _) in enumerate(triples)
    ]
