"""The comparison over a random sample of goal pairs: one paired unit per *pair*.

Episodes of one pair share its goals, so they are not independent evidence about goal pairs in
general; each pair is reduced to its per-method means over its episodes, and the tests run over
pairs (Wilcoxon signed-rank of AAIL's per-pair mean against the other method's), separately for
aligned and non-aligned pairs. JL is compared only on the pairs that have a joint network.

| measure       | per pair and method                                        |
|---------------|------------------------------------------------------------|
| `ego`         | mean ego return                                            |
| `others`      | mean partner return                                        |
| `team`        | mean team return                                           |
| `ego_success` | share of episodes ending with the ego inside its target    |
| `length`      | mean episode length                                        |
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from evaluation.config import PAPER_METHODS, Scenario
from evaluation.rollout import CellResult
from evaluation.stats import MeanSE, mean_se, paired_diff, wilcoxon_p

MEASURES: tuple[str, ...] = ("ego", "others", "team", "ego_success", "length")


@dataclass(frozen=True)
class PairMeans:
    scenario: Scenario
    by_method: dict[str, dict[str, float]]  # method -> measure -> mean over the pair's episodes


def pair_means(results: Sequence[CellResult]) -> list[PairMeans]:
    """Group cell results by pair scenario and reduce each to its per-method means."""
    grouped: dict[str, PairMeans] = {}
    for r in results:
        pm = grouped.setdefault(r.scenario.name, PairMeans(r.scenario, {}))
        pm.by_method[r.method] = {
            "ego": float(r.returns_EN[:, 0].mean()),
            "others": float(r.returns_EN[:, 1:].sum(axis=1).mean()),
            "team": float(r.team_E.mean()),
            "ego_success": float(r.success_EN[:, 0].mean()),
            "length": float(r.length_E.mean()),
        }
    return list(grouped.values())


@dataclass(frozen=True)
class PairTest:
    measure: str
    method: str
    other: str
    n_pairs: int
    diff: MeanSE  # mean over pairs of (method - other)
    p: float
    better: float  # share of pairs where `method` is better (higher; for length: lower)


@dataclass(frozen=True)
class PairGroup:
    """The pairs of one class (aligned or non-aligned)."""

    label: str
    pairs: tuple[PairMeans, ...]
    means: dict[str, dict[str, MeanSE]]  # method -> measure -> mean ± SE over pairs
    n_pairs: dict[str, int]  # method -> pairs it ran on
    tests: tuple[PairTest, ...]  # AAIL against every other method, every measure

    def test(self, method: str, other: str, measure: str) -> PairTest | None:
        """`method` against `other` over the pairs both ran on (None: no such pair)."""
        return pair_test(self.pairs, method, other, measure)


def pair_test(pairs: Sequence[PairMeans], method: str, other: str, measure: str) -> PairTest | None:
    both = [p for p in pairs if method in p.by_method and other in p.by_method]
    if not both:
        return None
    a = np.array([p.by_method[method][measure] for p in both])
    b = np.array([p.by_method[other][measure] for p in both])
    better = a < b if measure == "length" else a > b
    return PairTest(
        measure,
        method,
        other,
        len(both),
        paired_diff(a, b),
        wilcoxon_p(a, b),
        float(better.mean()),
    )


def summarise_group(label: str, pairs: Sequence[PairMeans], reference: str = "aail") -> PairGroup:
    present = {m for p in pairs for m in p.by_method}
    methods = [m for m in PAPER_METHODS if m in present] + sorted(present - set(PAPER_METHODS))
    means: dict[str, dict[str, MeanSE]] = {}
    counts: dict[str, int] = {}
    for method in methods:
        having = [p for p in pairs if method in p.by_method]
        counts[method] = len(having)
        means[method] = {m: mean_se([p.by_method[method][m] for p in having]) for m in MEASURES}
    tests = [
        pair_test(pairs, reference, other, measure)
        for other in methods
        if other != reference
        for measure in MEASURES
    ]
    return PairGroup(label, tuple(pairs), means, counts, tuple(t for t in tests if t))


def pair_groups(results: Sequence[CellResult]) -> list[PairGroup]:
    """Aligned and non-aligned groups (a group with no pair is left out)."""
    means = pair_means(results)
    groups = []
    for label, flag in (("aligned", True), ("non-aligned", False)):
        members = [p for p in means if p.scenario.aligned is flag]
        if members:
            groups.append(summarise_group(label, members))
    return groups
