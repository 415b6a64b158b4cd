"""Choosing the default likelihood on partner types the inference report does not score.

    python -m evaluation.inference.calibration --store-url URL [--out reports/inference]

The likelihood a session scores a partner's actions with has two settings: its temperature
(`LIKELIHOOD_TEMPERING` × each task network's training α) and its uniform action noise η
(`policy.belief.DEFAULT_NOISE`): p(a | s, g) = (1 - η) softmax(Q_g(s, ·) / α)[a] + η / |A|.
Both are chosen here, on the partner types in `CALIBRATION_TYPES` only (the report's bar is
judged on the others), with coexist's own networks (`same`) as a guard.

Per partner type, one accuracy run (`run_accuracy`, k up to `PARTNER_K`) tracks every candidate
on the same trajectories: the ego is driven by the first candidate, the likelihood of before the
noise (2 × the training α, η = 0), so the candidates differ by their likelihood alone. The
measure is the report's: the true goal among the three most likely after `PARTNER_K` actions.

Rule, fixed before the run: the candidate with the highest mean top-3 over the calibration types
(ties: the smaller η, then the tempering closer to 2); it becomes the default only if that mean
is above the first candidate's and its top-3 with `same` is not below the first candidate's.
`calibration.json` holds every number; `evaluation.inference.report` renders it.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.command_line import portable_command
from evaluation.inference.accuracy import AccuracyConfig, run_accuracy
from evaluation.inference.suite import CALIBRATION_TYPES, PARTNER_K
from policy.belief import BeliefConfig
from services.engine import InferenceEngine

CALIBRATION = "calibration.json"
GUARD_TYPE = "same"  # the default may not get worse against coexist's own networks
TEMPERINGS = (0.25, 1.0, 2.0, 4.0, 8.0)  # × each task network's training α
NOISES = (0.0, 0.02, 0.05, 0.1, 0.2, 0.3)
INCUMBENT = (2.0, 0.0)  # the likelihood before the noise: drives the ego, the bar to beat


@dataclass(frozen=True)
class Candidate:
    tempering: float  # × the training α
    noise: float  # η

    @property
    def label(self) -> str:
        return f"{self.tempering:g} × α, η = {self.noise:g}"

    def belief(self, training_alpha: float) -> BeliefConfig:
        return BeliefConfig(temperature=self.tempering * training_alpha, noise=self.noise)


def candidates() -> list[Candidate]:
    """Every tempering × noise pair, the incumbent first (it drives the ego)."""
    grid = [Candidate(t, n) for t in TEMPERINGS for n in NOISES]
    incumbent = Candidate(*INCUMBENT)
    return [incumbent] + [c for c in grid if c != incumbent]


def training_alpha(engine: InferenceEngine, alias: str, env: str = "particle") -> float:
    """The task networks' common training α (the tempering multiplies it); ValueError when
    they differ (a tempering factor would then not be one temperature)."""
    from services.engine.environments import env_runtime
    from services.engine.goal_inference import task_group

    group = task_group(engine.cache, env_runtime(env), alias, {})
    alphas = np.unique(np.asarray(group.alpha_G, dtype=np.float64))
    if alphas.size != 1:
        raise ValueError(f"alias: the task networks' training α differ ({alphas.tolist()})")
    return float(alphas[0])


def choose(top3: dict[str, list[float]], cands: list[Candidate]) -> tuple[int, bool]:
    """The best candidate by the rule of the module docstring, and whether it beats the
    incumbent (index 0) on the calibration types without losing on `GUARD_TYPE`."""
    mean = np.mean([top3[t] for t in CALIBRATION_TYPES], axis=0)
    order = sorted(
        range(len(cands)),
        key=lambda i: (-round(float(mean[i]), 9), cands[i].noise, abs(cands[i].tempering - 2.0)),
    )
    best = order[0]
    better = bool(mean[best] > mean[0] and top3[GUARD_TYPE][best] >= top3[GUARD_TYPE][0])
    return best, better


def run_calibration(
    engine: InferenceEngine,
    *,
    episodes_per_goal: int = 6,
    seed: int = 7,
    alias: str = "production",
    partner_alias: str = "partners",
    k: int = PARTNER_K,
) -> dict[str, Any]:
    """Every candidate against every calibration type and `GUARD_TYPE` (module docstring)."""
    cands = candidates()
    alpha = training_alpha(engine, alias)
    beliefs = tuple(c.belief(alpha) for c in cands)
    types = (*CALIBRATION_TYPES, GUARD_TYPE)
    top1: dict[str, list[float]] = {}
    top3: dict[str, list[float]] = {}
    episodes = 0
    for name in types:
        config = AccuracyConfig(
            episodes_per_goal=episodes_per_goal,
            k_max=k,
            seed=seed,
            beliefs=beliefs,
            alias=alias,
            partner_alias=partner_alias,
            partner_type=name,
        )
        result = run_accuracy(engine, config)
        episodes = int(result.top3_CEK.shape[1])
        top1[name] = result.top1_CEK[:, :, k].mean(axis=1).round(4).tolist()
        top3[name] = result.top3_CEK[:, :, k].mean(axis=1).round(4).tolist()
    best, better = choose(top3, cands)
    return {
        "k": k,
        "seed": seed,
        "episodes": episodes,
        "training_alpha": alpha,
        "types": list(types),
        "calibration_types": list(CALIBRATION_TYPES),
        "candidates": [{"tempering": c.tempering, "noise": c.noise} for c in cands],
        "top1": top1,
        "top3": top3,
        "best": best,
        "adopted": better,
    }


def main(argv: list[str] | None = None) -> int:
    from model_store.defaults import open_store

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--store-url", required=True)
    parser.add_argument("--episodes-per-goal", type=int, default=6)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--alias", default="production")
    parser.add_argument("--partner-alias", default="partners")
    parser.add_argument("--out", type=Path, default=Path("reports/inference"))
    args = parser.parse_args(argv)
    with open_store(args.store_url) as store:
        results = run_calibration(
            InferenceEngine(store),
            episodes_per_goal=args.episodes_per_goal,
            seed=args.seed,
            alias=args.alias,
            partner_alias=args.partner_alias,
        )
    words = ["python", "-m", "evaluation.inference.calibration", "--store-url", args.store_url]
    words += ["--episodes-per-goal", str(args.episodes_per_goal), "--seed", str(args.seed)]
    words += ["--alias", args.alias, "--partner-alias", args.partner_alias]
    words += ["--out", str(args.out)]
    results["command"] = portable_command(words)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / CALIBRATION).write_text(json.dumps(results, indent=1))
    print(calibration_table(results))
    return 0


def calibration_table(results: dict[str, Any]) -> str:
    """The candidates' top-3 per partner type (markdown), the chosen one in bold."""
    from evaluation.paper.tables import table

    cands = [Candidate(c["tempering"], c["noise"]) for c in results["candidates"]]
    calib, types = results["calibration_types"], results["types"]
    rows = []
    for i, cand in enumerate(cands):
        mean = float(np.mean([results["top3"][t][i] for t in calib]))
        cells = [f"{results['top3'][t][i]:.3f}" for t in types]
        label = cand.label + (" (before)" if i == 0 else "")
        row = [label, *cells, f"{mean:.3f}"]
        if i == results["best"]:
            row = [f"**{cell}**" for cell in row]
        rows.append(row)
    header = ["likelihood", *types, "mean of " + ", ".join(calib)]
    return table(header, rows)


if __name__ == "__main__":
    sys.exit(main())
