"""Every method against every partner type (`evaluation.partner_types`) on goal pairs and five-agent
goal sets drawn with the run's seed: the episodes of `coexist eval --suite partners`.

Pairs come from two strict classes (`envs.particle.scenarios`): aligned pairs whose target
strictly contains the partner's influence area (`room_to_help`: where the paper says blending
helps) and non-aligned pairs (where helping costs the ego). Five-agent goal sets are drawn from
the whole catalogue. Every method of one partner type meets the same starts and random numbers
(`evaluation.rollout`); each partner type has its own starts (a new draw of the same pairs).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from envs.particle.scenarios import room_to_help, sample_goal_sets, sample_pairs_of_class
from evaluation.backend import PolicyBackend
from evaluation.config import Scenario
from evaluation.partner_types import PARTNER_TYPES, partner_type
from evaluation.rollout import Cell, CellResult, run_cells

METHODS: tuple[str, ...] = ("sl", "aail", "aail_bounded", "aail_budget")
CLASSES: tuple[str, ...] = ("aligned", "non_aligned", "five_agents")


@dataclass(frozen=True)
class PartnersConfig:
    """One run's settings (`coexist eval --suite partners`' options)."""

    seed: int = 0
    aligned_pairs: int = 12
    non_aligned_pairs: int = 12
    pair_episodes: int = 20
    five_agent_sets: int = 4
    set_episodes: int = 50
    max_steps: int = 400
    partner_types: tuple[str, ...] = tuple(PARTNER_TYPES)
    methods: tuple[str, ...] = METHODS
    budget: float | None = None  # aail_budget's budget B (None: the engine's default)
    alias: str = "production"
    partner_alias: str = "partners"

    def __post_init__(self) -> None:
        for name in ("pair_episodes", "set_episodes", "max_steps"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}: expected >= 1, got {getattr(self, name)}")
        for name in ("aligned_pairs", "non_aligned_pairs", "five_agent_sets"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name}: expected >= 0, got {getattr(self, name)}")
        for name in self.partner_types:
            partner_type(name)  # ValueError naming the known types
        if "sl" not in self.methods:
            raise ValueError("methods: every comparison is against SL; sl is missing")


def scenarios(config: PartnersConfig, kind: int = 0) -> dict[str, list[Scenario]]:
    """The run's pairs and sets by class; `kind` (the partner type's position) offsets the
    starts so that each partner type meets its own start states."""
    base = 1000 * config.seed
    pool = [p for p in sample_pairs_of_class(base + 7, "aligned", 10_000) if room_to_help(*p)]
    picks = np.random.default_rng(base + 8).permutation(len(pool))[: config.aligned_pairs]
    aligned = [pool[i] for i in sorted(picks.tolist())]
    non_aligned = sample_pairs_of_class(base + 9, "non_aligned", config.non_aligned_pairs)
    sets = sample_goal_sets(base + 11, config.five_agent_sets, 5)
    start = base + 100 + 10_000 * kind

    def pairs(label: str, drawn: Sequence[tuple[str, ...]], episodes: int) -> list[Scenario]:
        return [
            Scenario(f"{label}:{'+'.join(g)}", g[0], tuple(g[1:]), episodes, start + i)
            for i, g in enumerate(drawn)
        ]

    return {
        "aligned": pairs("aligned", aligned, config.pair_episodes),
        "non_aligned": pairs("non_aligned", non_aligned, config.pair_episodes),
        "five_agents": pairs("set", sets, config.set_episodes),
    }


@dataclass
class PartnersResult:
    """Every cell of a run: partner type -> class -> the cells (scenario × method)."""

    config: PartnersConfig
    cells: dict[str, dict[str, list[CellResult]]] = field(default_factory=dict)
    backend_calls: int = 0

    def cell(self, ptype: str, kind: str, scenario: str, method: str) -> CellResult:
        for c in self.cells[ptype][kind]:
            if c.scenario.name == scenario and c.method == method:
                return c
        raise KeyError((ptype, kind, scenario, method))


Progress = Callable[[str, int], Callable[[int, int], None]]


def run_partners(
    backend: PolicyBackend, config: PartnersConfig, progress: Progress | None = None
) -> PartnersResult:
    """Run every (partner type, class) block of cells; one `run_cells` call per block."""
    result = PartnersResult(config)
    for k, name in enumerate(config.partner_types):
        kind = partner_type(name)
        by_class = scenarios(config, k)
        result.cells[name] = {}
        for label, chosen in by_class.items():
            cells = [Cell(s, m) for s in chosen for m in config.methods]
            if not cells:
                result.cells[name][label] = []
                continue
            advance = None if progress is None else progress(f"{name} {label}", config.max_steps)
            out = run_cells(
                backend,
                cells,
                max_steps=config.max_steps,
                seed=config.seed + 17 * k,
                alias=config.alias,
                partner_alias=config.partner_alias,
                partner_type=kind,
                budget=config.budget,
                progress=advance,
            )
            result.cells[name][label] = out.results
            result.backend_calls += out.backend_calls
    return result
