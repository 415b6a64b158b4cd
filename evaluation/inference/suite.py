"""`coexist eval --suite inference`: the goal-inference experiments end to end, as JSON.

    results = run_inference_suite(engine, store, InferenceSuiteConfig())
    write_results(results, out)                      # out/results.json + figures + README.md

| part       | what                                                                     | module             |
|------------|--------------------------------------------------------------------------|--------------------|
| check      | every network the runs need is served (fails before any episode)        | here               |
| networks   | which versions each population has, with their gate verdicts            | here               |
| accuracy   | belief vs k, 35 goals × 6 seeds, for the server's default belief        | `inference`        |
|            | (λ 0.95, ε 1e-3), λ = 1, plain Bayes (λ 1, ε 0), λ = 0.8, a tempered    |                    |
|            | likelihood (α = 0.1, 5× the training α) and the default without its     |                    |
|            | uniform action noise (η = 0), on the same trajectories                  |                    |
| matched    | the default belief when the partner is driven by the likelihood         | `inference`        |
|            | networks themselves (`partner_alias` = `alias`): what model mismatch    |                    |
|            | costs                                                                   |                    |
| switch     | the settings above, the partner changing its goal at k = 25             | `inference`        |
| partners   | the default belief against every partner type that acts towards its goal | `inference`        |
|            | (`evaluation.partner_types`): top-3 after `PARTNER_K` actions; the types |                    |
|            | in `CALIBRATION_TYPES` chose the likelihood (tempering and noise:        |                    |
|            | `inference.calibration`) and are not scored by the bar                   |                    |
| value      | SL, AAIL announced, AAIL inferred on the paper's scenarios and pairs    | `inference_value`  |

`results.json` holds every number the report shows (the figures and README are drawn from it by
`evaluation.inference.report`, so the latency benchmark can re-render the README later).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from envs.particle.goals import GOAL_IDS
from evaluation.inference.accuracy import (
    AccuracyConfig,
    AccuracyResult,
    belief_label,
    run_accuracy,
)
from evaluation.inference.value import Comparison, ValueConfig, ValueResult, run_value
from model_store.errors import ModelStoreError
from model_store.naming import impact_model_name, task_model_name
from model_store.store import ModelStore
from policy.belief import DEFAULT_NOISE, BeliefConfig
from services.engine import InferenceEngine

ProgressFactory = Callable[[str, int], Callable[[int, int], None]]  # (label, total) -> callback
# partner types for goal inference (an idle or switching partner shows no goal to infer)
INFERENCE_PARTNER_TYPES = ("same", "other_seed", "eps_0.1", "eps_0.3", "hot", "scripted")
# chose the likelihood (`LIKELIHOOD_TEMPERING`, `DEFAULT_NOISE`: `evaluation.inference.calibration`)
CALIBRATION_TYPES = ("eps_0.3", "hot", "scripted")
PARTNER_K = 30  # the bar: top-3 after 30 actions within 5 points of the own networks' ("same")
REPORT_KS = (1, 5, 10, 20, 50)
SUITE_BELIEFS = (
    BeliefConfig(),  # the server's default: drives the ego
    BeliefConfig(forgetting=1.0),
    BeliefConfig(forgetting=1.0, floor=0.0),  # plain Bayes
    BeliefConfig(forgetting=0.8),
    BeliefConfig(temperature=0.1),  # tempered: 5x the networks' training α of 0.02
    # the default likelihood without its uniform action noise: what the noise changes
    *((BeliefConfig(noise=0.0),) if DEFAULT_NOISE else ()),
)


@dataclass(frozen=True)
class InferenceSuiteConfig:
    accuracy: AccuracyConfig = field(default_factory=lambda: AccuracyConfig(beliefs=SUITE_BELIEFS))
    switch_at: int = 25
    value: ValueConfig = field(default_factory=ValueConfig)
    fast: bool = False

    @property
    def switch(self) -> AccuracyConfig:
        return replace(self.accuracy, switch_at=self.switch_at)

    def partner(self, name: str) -> AccuracyConfig:
        """The default belief alone against partner type `name`."""
        acc = self.accuracy
        return replace(acc, partner_type=name, beliefs=acc.beliefs[:1])

    @property
    def matched(self) -> AccuracyConfig:
        """The default belief alone, the partner driven by the likelihood networks."""
        acc = self.accuracy
        return replace(acc, partner_alias=acc.alias, beliefs=acc.beliefs[:1])


def fast_inference_config(seed: int = 0) -> InferenceSuiteConfig:
    """A few short runs: they test the harness, not the method."""
    return InferenceSuiteConfig(
        accuracy=AccuracyConfig(episodes_per_goal=1, k_max=12, seed=seed, beliefs=SUITE_BELIEFS),
        switch_at=6,
        value=ValueConfig(
            episodes=4, pairs=3, pair_episodes=2, max_steps=40, seed=seed, bootstrap=200
        ),
        fast=True,
    )


def needed_networks(config: InferenceSuiteConfig) -> list[str]:
    """`name@alias` of every network the suite reads: all task and impact networks of the
    ego's population (likelihoods over 35 goals, impact nets of any goal the belief blends)
    and the partner population's task networks."""
    acc, env = config.accuracy, config.accuracy.env
    names = [f"{task_model_name(env, g)}@{acc.alias}" for g in GOAL_IDS]
    names += [f"{impact_model_name(env, g)}@{acc.alias}" for g in GOAL_IDS]
    names += [f"{task_model_name(env, g)}@{acc.partner_alias}" for g in GOAL_IDS]
    return names


def missing_networks(store: ModelStore, config: InferenceSuiteConfig) -> list[str]:
    missing = []
    for ref in needed_networks(config):
        try:
            store.resolve(ref)
        except ModelStoreError:
            missing.append(ref)
    return missing


def networks_summary(store: ModelStore, config: InferenceSuiteConfig) -> list[dict[str, Any]]:
    """Per population (task@alias, impact@alias, task@partner_alias): how many networks, their
    training seeds and quality-gate verdicts, from the lineage of the resolved versions."""
    rows: dict[str, dict[str, Any]] = {}
    for ref in needed_networks(config):
        version = store.resolve(ref)
        kind = version.name.split("/")[1]
        key = f"{kind}@{ref.rsplit('@', 1)[1]}"
        row = rows.setdefault(
            key,
            {
                "population": key,
                "networks": 0,
                "seeds": set(),
                "gate": {"passed": 0, "failed": 0, "none": 0},
            },
        )
        row["networks"] += 1
        row["seeds"].add(version.lineage.seed)
        gate = version.lineage.metrics.get("gate")
        passed = gate.get("passed") if isinstance(gate, dict) else None
        row["gate"]["none" if passed is None else ("passed" if passed else "failed")] += 1
    for row in rows.values():
        row["seeds"] = sorted(s for s in row["seeds"] if s is not None)
    return list(rows.values())


def accuracy_json(result: AccuracyResult) -> dict[str, Any]:
    cfg = result.config
    k = min(cfg.k_max, 50)
    return {
        "config": asdict(cfg) | {"beliefs": [belief_label(b) for b in cfg.beliefs]},
        "episodes": int(result.top1_CEK.shape[1]),
        "wall_s": round(result.wall_s, 2),
        "series": result.summary(),
        "confusions_at_k": k,
        "confusions": [list(c) for c in result.confusions(k)],
    }


def partner_json(result: AccuracyResult) -> dict[str, Any]:
    """One partner type's default belief: top-1 and top-3 after min(PARTNER_K, k_max) actions."""
    k = min(PARTNER_K, result.config.k_max)
    return {
        "k": k,
        "episodes": int(result.top1_CEK.shape[1]),
        "top1": float(result.top1_CEK[0, :, k].mean()),
        "top3": float(result.top3_CEK[0, :, k].mean()),
        "calibration": result.config.partner_type in CALIBRATION_TYPES,
    }


def _comparison_json(c: Comparison) -> dict[str, Any]:
    return {
        "units": c.units,
        "means": {m: {k: [v.mean, v.se] for k, v in by.items()} for m, by in c.means.items()},
        "ego_success": c.ego_success,
        "diffs": {k: {"mean": d.mean, "se": d.se, "p": p} for k, (d, p) in c.diffs.items()},
        "recovered": [None if math.isnan(x) else x for x in c.recovered],  # JSON has no NaN
        "belief_top1_at_end": c.belief_top1,
    }


def value_json(result: ValueResult) -> dict[str, Any]:
    cfg = result.config
    episodes: dict[str, dict[str, Any]] = {}
    for cell in result.cells:
        episodes.setdefault(cell.scenario.name, {})[cell.method] = {
            "returns": cell.returns_EN.round(4).tolist(),
            "success": cell.success_EN[:, 0].tolist(),
            "length": cell.length_E.tolist(),
        }
    return {
        "config": asdict(cfg) | {"belief": asdict(cfg.belief)},
        "wall_s": {k: round(v, 2) for k, v in result.wall_s.items()},
        "scenarios": {k: _comparison_json(c) for k, c in result.scenarios.items()},
        "pair_groups": {k: _comparison_json(c) for k, c in result.pair_groups.items()},
        "episodes": episodes,
    }


def run_inference_suite(
    engine: InferenceEngine,
    store: ModelStore,
    config: InferenceSuiteConfig,
    *,
    command: str,
    progress: ProgressFactory | None = None,
) -> dict[str, Any]:
    """Every part of the module docstring; the JSON of `results.json`. LookupError (naming the
    networks) when the store lacks one, before any episode runs."""
    missing = missing_networks(store, config)
    if missing:
        raise LookupError(
            "networks the inference suite needs are not served: " + ", ".join(missing)
        )

    def bar(label: str, total: int) -> Callable[[int, int], None] | None:
        return progress(label, total) if progress else None

    k_max = config.accuracy.k_max
    accuracy = run_accuracy(engine, config.accuracy, progress=bar("accuracy", k_max))
    matched = run_accuracy(engine, config.matched, progress=bar("matched networks", k_max))
    switch = run_accuracy(engine, config.switch, progress=bar("goal switch", k_max))
    value_bars = {}
    max_steps = config.value.max_steps

    def value_progress(label: str, t: int, active: int) -> None:
        if progress is None:
            return
        if label not in value_bars:
            value_bars[label] = progress(f"value: {label}", max_steps)
        value_bars[label](t, active)

    value = run_value(engine, config.value, progress=value_progress)
    partners = {}
    for name in INFERENCE_PARTNER_TYPES:
        result = run_accuracy(
            engine, config.partner(name), progress=bar(f"partners: {name}", k_max)
        )
        partners[name] = partner_json(result)
    return {
        "command": command,
        "fast": config.fast,
        "networks": networks_summary(store, config),
        "accuracy": accuracy_json(accuracy),
        "matched": accuracy_json(matched),
        "switch": accuracy_json(switch),
        "value": value_json(value),
        "partners": partners,
    }


def write_results(results: dict[str, Any], out: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.json"
    path.write_text(json.dumps(results, default=_json_default))
    return path


def _json_default(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
