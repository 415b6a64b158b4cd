"""The paper suite end to end: episodes, direction fields, training costs, then the report.

    result = run_suite(config, backend, store)       # episodes and measurements
    write_report(result, out_dir, command=...)        # evaluation.paper.report: REPORT.md + PNGs

| step         | what                                                                 |
|--------------|----------------------------------------------------------------------|
| JL check     | which scenarios have a joint network (JL runs only there)            |
| two agents   | aligned + non-aligned scenarios, every method, one batched world     |
| five agents  | the five-agent scenario                                              |
| pairs        | goal pairs drawn per strict class, every replicate (JL where trained) |
| goal sets    | five-agent goal sets drawn from the whole catalogue                  |
| fields       | Fig. 6 direction fields for the non-aligned scenario                 |
| training     | lineage curve summaries and costs (needs the store)                  |

Every episode's returns are kept to `RETURN_DECIMALS` decimals as soon as they are measured, so
that the report's statistics and the results.json it ships are the same numbers: a reader (and
`tests/evaluation/paper/test_eval_report.py`) recomputes every table from the file alone.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from evaluation.backend import ModelRecord, PolicyBackend
from evaluation.config import (
    Scenario,
    SuiteConfig,
    goal_set_scenarios,
    pair_scenarios,
    paper_scenarios,
)
from evaluation.paper.directions import DirectionField, direction_fields
from evaluation.paper.scaling import KindTraining, registered_versions, training_costs
from evaluation.rollout import Cell, CellResult, ProgressFn, run_cells
from evaluation.timing import read_log
from model_store.store import ModelStore
from services.engine import ActRequest, PartnerSpec

# (description, total steps) -> per-step callback
ProgressFactory = Callable[[str, int], ProgressFn]


RETURN_DECIMALS = 4  # an episode's returns, as measured and as results.json keeps them


@dataclass
class SuiteResult:
    config: SuiteConfig
    backend: str
    scenarios: list[Scenario]
    cells: dict[str, dict[str, CellResult]]  # scenario name -> method -> result
    pair_results: list[CellResult]  # goal pairs and five-agent goal sets (`evaluation.paper.pairs`)
    jl_available: dict[str, bool]  # scenario name -> a joint network exists
    models: set[tuple[str, ModelRecord]] = field(default_factory=set)
    wall_s: dict[str, float] = field(default_factory=dict)
    backend_calls: int = 0
    fields: list[DirectionField] = field(default_factory=list)
    training: list[KindTraining] = field(default_factory=list)
    curves: dict[str, list[dict[str, float]]] = field(default_factory=dict)
    gates: dict[tuple[str, int], str] = field(default_factory=dict)  # (name, version) -> verdict


def has_joint_network(backend: PolicyBackend, scenario: Scenario, config: SuiteConfig) -> bool:
    probe = ActRequest(
        env=config.ENV,
        ego_goal=scenario.ego_goal,
        observations=np.full((1, 4 * scenario.n_agents), 0.5, dtype=np.float32),
        partners=tuple(PartnerSpec(j, goal=g) for j, g in enumerate(scenario.partner_goals, 1)),
        method="jl",
        alias=config.alias,
    )
    return backend.has_models(probe)


def missing_networks(
    backend: PolicyBackend, scenarios: Sequence[Scenario], config: SuiteConfig
) -> list[str]:
    """The AAIL networks (ego task + impacts) and partner task networks that cannot be served,
    as `name@alias` strings; checked before any episode runs, so a gap fails at once."""
    missing: list[str] = []
    for s in scenarios:
        obs = np.full((1, 4 * s.n_agents), 0.5, dtype=np.float32)
        partners = tuple(PartnerSpec(j, goal=g) for j, g in enumerate(s.partner_goals, 1))
        probe = ActRequest(config.ENV, s.ego_goal, obs, partners, method="aail", alias=config.alias)
        if not backend.has_models(probe):
            missing.append(f"{s.combo}: ego task or impact networks @{config.alias}")
        for goal in s.partner_goals:
            probe = ActRequest(config.ENV, goal, obs, method="sl", alias=config.partner_alias)
            if not backend.has_models(probe):
                missing.append(f"{config.ENV}/task/{goal}@{config.partner_alias}")
    return sorted(set(missing))


def _methods(config: SuiteConfig, jl: bool) -> list[str]:
    return [m for m in config.methods if m != "jl" or jl]


def _curves(store: ModelStore, env: str) -> dict[str, list[dict[str, float]]]:
    curves: dict[str, list[dict[str, float]]] = {}
    for kind, version in registered_versions(store, env):
        summary = version.lineage.metrics.get("curve")
        if isinstance(summary, dict) and summary:
            curves.setdefault(kind, []).append(
                {k: float(v) for k, v in summary.items() if isinstance(v, int | float)}
            )
    return curves


def gate_verdicts(store: ModelStore, models: Iterable[ModelRecord]) -> dict[tuple[str, int], str]:
    """The quality-gate verdict in each version's lineage: passed, failed or none (no gate)."""
    verdicts = {}
    for m in models:
        gate = store.get_version(m.name, m.version).lineage.metrics.get("gate")
        passed = gate.get("passed") if isinstance(gate, dict) else None
        verdicts[(m.name, m.version)] = (
            "none" if passed is None else ("passed" if passed else "failed")
        )
    return verdicts


def run_suite(
    config: SuiteConfig,
    backend: PolicyBackend,
    store: ModelStore | None,
    *,
    timing_log: Path | None = None,
    progress: ProgressFactory | None = None,
) -> SuiteResult:
    """Every experiment of the suite (module docstring)."""
    scenarios, pairs = paper_scenarios(config), pair_scenarios(config)
    sets = goal_set_scenarios(config)
    missing = missing_networks(backend, scenarios + pairs + sets, config)
    if missing:
        raise LookupError("networks the suite needs are not served: " + "; ".join(missing))
    want_jl = "jl" in config.methods
    jl = {
        s.name: want_jl and has_joint_network(backend, s, config) for s in scenarios + pairs + sets
    }
    result = SuiteResult(config, backend.description, scenarios, {}, [], jl)

    def run(label: str, chosen: Sequence[Scenario]) -> list[CellResult]:
        cells = [Cell(s, m) for s in chosen for m in _methods(config, jl[s.name])]
        start = time.perf_counter()
        out = run_cells(
            backend,
            cells,
            max_steps=config.max_steps,
            seed=config.seed,
            alias=config.alias,
            partner_alias=config.partner_alias,
            env=config.ENV,
            progress=progress(label, config.max_steps) if progress else None,
            regret_bound=config.regret_bound,
        )
        result.wall_s[label] = time.perf_counter() - start
        result.models |= out.models
        result.backend_calls += out.backend_calls
        return [replace(r, returns_EN=r.returns_EN.round(RETURN_DECIMALS)) for r in out.results]

    two = [s for s in scenarios if s.n_agents == 2]
    many = [s for s in scenarios if s.n_agents != 2]
    for r in run("two-agent scenarios", two) + (run("five agents", many) if many else []):
        result.cells.setdefault(r.scenario.name, {})[r.method] = r
    if pairs:
        result.pair_results = run(f"{len(pairs)} goal pairs", pairs)
    if sets:
        result.pair_results += run(f"{len(sets)} five-agent goal sets", sets)

    start = time.perf_counter()
    non_aligned = next(s for s in scenarios if s.name == "non_aligned")
    result.fields = direction_fields(
        backend,
        store,
        non_aligned.ego_goal,
        non_aligned.partner_goals[0],
        alias=config.alias,
        env=config.ENV,
    )
    result.wall_s["direction fields"] = time.perf_counter() - start
    if store is not None:
        versions = registered_versions(store, config.ENV)
        log = read_log(timing_log) if timing_log is not None else []
        result.training = training_costs(versions, log)
        result.curves = _curves(store, config.ENV)
        result.gates = gate_verdicts(store, {m for _, m in result.models})
    return result


def _cell_json(c: CellResult) -> dict[str, object]:
    return {
        "goals": list(c.scenario.goals),
        "replicate": c.scenario.replicate,
        "start_seed": c.scenario.start_seed,
        "method": c.method,
        "returns": c.returns_EN.round(RETURN_DECIMALS).tolist(),
        "success": c.success_EN.tolist(),
        "reached": c.reached_EN.tolist(),
        "length": c.length_E.tolist(),
        "solved": c.solved_E.tolist(),
    }


def results_json(result: SuiteResult) -> dict[str, object]:
    """Every episode's numbers, keyed by `scenario/method`, and the suite's settings."""
    cells = [c for by in result.cells.values() for c in by.values()] + result.pair_results
    config = vars(result.config) | {"methods": list(result.config.methods)}
    return {
        "config": config,
        "cells": {f"{c.scenario.name}/{c.method}": _cell_json(c) for c in cells},
    }
