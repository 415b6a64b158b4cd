"""Goal pairs and five-agent goal sets nobody tuned on: one paired unit per pair (or set).

Episodes of one pair share its goals, so they are not independent evidence about goal pairs in
general: each pair is reduced to its per-method means over all its episodes (pooled over the
replicates that drew it), and the tests run over pairs (Wilcoxon signed-rank of one method's
per-pair mean against another's), separately for each strict class (`envs.particle.scenarios`).
JL is compared only on the pairs that have a joint network.

Each class is one family of tests for Holm's correction (`class_family`): every comparison of
`CLASS_COMPARISONS` on every measure of `FAMILY_MEASURES` that ran in it, the tests its table
prints; the targets (`evaluation.targets`) read their p from the same family.

| measure       | per unit and method                                               |
|---------------|-------------------------------------------------------------------|
| `ego`         | mean ego return                                                   |
| `others`      | mean return of the other agents together                          |
| `team`        | mean team return                                                  |
| `ego_success` | share of episodes ending with the ego inside its target           |
| `stuck`       | share of episodes ending with the ego *outside* its target: it    |
|               | never reached it (`never`) or left it and did not come back      |
| `never`       | share of episodes in which the ego never reached its target       |
| `length`      | mean episode length                                               |

Regret of a method on a unit: (SL ego − method ego) / |SL ego|, the ego's own-return loss against
the task network alone (the paper's "regret of using a compound policy"). A stuck episode is the
worst outcome for a user (the robot strands itself and every agent pays for every step until the
limit), so stuck episodes are counted, not averaged away: per class, per method and per pair, with
the worst pairs listed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from evaluation.config import PAPER_METHODS, Scenario
from evaluation.rollout import CellResult
from evaluation.stats import (
    Interval,
    MeanSE,
    Tost,
    mean_se,
    paired_ci,
    paired_diff,
    rank_biserial,
    tost_paired,
    wilcoxon_p,
    with_holm,
)

MEASURES: tuple[str, ...] = ("ego", "others", "team", "ego_success", "stuck", "never", "length")
TEAM_TOLERANCE = 0.02  # "at least SL's within 2 %": team >= SL - 0.02 |SL|


@dataclass(frozen=True)
class Unit:
    """One goal pair (or goal set), its episodes pooled over the replicates that drew it."""

    combo: str
    scenarios: tuple[Scenario, ...]
    by_method: dict[str, dict[str, float]]  # method -> measure -> mean over its episodes
    stuck_episodes: dict[str, int]  # method -> episodes the ego ended outside its target
    episodes: int

    @property
    def pair_class(self) -> str | None:
        return self.scenarios[0].pair_class

    @property
    def room_to_help(self) -> bool:
        return self.scenarios[0].room_to_help

    def regret(self, method: str) -> float:
        """(SL ego − method ego) / |SL ego| (0 when both are 0)."""
        sl, ego = self.by_method["sl"]["ego"], self.by_method[method]["ego"]
        if sl == 0.0:
            return 0.0 if ego == 0.0 else float("inf")
        return (sl - ego) / abs(sl)

    def team_within(self, method: str, tolerance: float = TEAM_TOLERANCE) -> bool:
        """Whether the method's team return is at least SL's within `tolerance` × |SL|."""
        sl, team = self.by_method["sl"]["team"], self.by_method[method]["team"]
        return team >= sl - tolerance * abs(sl)


def _episode_measures(r: CellResult) -> dict[str, np.ndarray]:
    stuck = ~r.success_EN[:, 0]
    return {
        "ego": r.returns_EN[:, 0],
        "others": r.returns_EN[:, 1:].sum(axis=1),
        "team": r.team_E,
        "ego_success": r.success_EN[:, 0].astype(float),
        "stuck": stuck.astype(float),
        "never": (~r.reached_EN[:, 0]).astype(float),
        "length": r.length_E.astype(float),
    }


def units_of(results: Sequence[CellResult]) -> list[Unit]:
    """Group cell results by goal combination (over replicates) into units."""
    episodes: dict[str, dict[str, list[dict[str, np.ndarray]]]] = {}
    scenarios: dict[str, dict[str, Scenario]] = {}
    for r in results:
        combo = r.scenario.combo
        episodes.setdefault(combo, {}).setdefault(r.method, []).append(_episode_measures(r))
        scenarios.setdefault(combo, {})[r.scenario.name] = r.scenario
    units = []
    for combo, by_method in episodes.items():
        means: dict[str, dict[str, float]] = {}
        stuck: dict[str, int] = {}
        for method, parts in by_method.items():
            pooled = {m: np.concatenate([p[m] for p in parts]) for m in MEASURES}
            means[method] = {m: float(v.mean()) for m, v in pooled.items()}
            stuck[method] = int(pooled["stuck"].sum())
        n = int(sum(len(p["ego"]) for p in by_method["sl"])) if "sl" in by_method else 0
        units.append(Unit(combo, tuple(scenarios[combo].values()), means, stuck, n))
    return units


@dataclass(frozen=True)
class UnitTest:
    measure: str
    method: str
    other: str
    n_units: int
    diff: MeanSE  # mean over units of (method - other)
    p: float  # Wilcoxon signed-rank over units
    better: float  # share of units where `method` is better (higher; for length, stuck: lower)
    ci: Interval  # 95 % t interval of the mean difference over units
    effect: float  # matched-pairs rank-biserial correlation over units
    p_holm: float | None = None  # Holm-adjusted within its class (`class_family`)


@dataclass(frozen=True)
class MethodRow:
    """One method over a group of units."""

    method: str
    n_units: int
    means: dict[str, MeanSE]  # measure -> mean ± SE over units
    stuck_episodes: int
    episodes: int
    units_with_stuck: int
    regret_median: float
    regret_mean: float
    team_within_share: float  # units with team >= SL - 2 % |SL|
    team_above_share: float  # units with team > SL


@dataclass(frozen=True)
class UnitGroup:
    """The units of one class (aligned, non-aligned, mixed, their room-to-help subset, or the
    five-agent goal sets)."""

    label: str
    units: tuple[Unit, ...]
    rows: dict[str, MethodRow]

    def test(self, method: str, other: str, measure: str) -> UnitTest | None:
        return unit_test(self.units, method, other, measure)

    def tost(self, method: str, other: str, measure: str, margin_fraction: float) -> Tost | None:
        """Paired TOST over the units both methods ran, `other` the reference."""
        a, b = _unit_values(self.units, method, other, measure)
        return tost_paired(a, b, margin_fraction=margin_fraction) if a.size else None

    def worst(self, method: str, k: int = 8) -> list[Unit]:
        """The units where `method` strands the ego most often, then with the largest regret."""
        having = [u for u in self.units if method in u.by_method and "sl" in u.by_method]
        ranked = sorted(having, key=lambda u: (-u.stuck_episodes[method], -u.regret(method)))
        return ranked[:k]


LOWER_IS_BETTER = ("length", "stuck", "never")


def _unit_values(
    units: Sequence[Unit], method: str, other: str, measure: str
) -> tuple[np.ndarray, np.ndarray]:
    both = [u for u in units if method in u.by_method and other in u.by_method]
    a = np.array([u.by_method[method][measure] for u in both])
    b = np.array([u.by_method[other][measure] for u in both])
    return a, b


def unit_test(units: Sequence[Unit], method: str, other: str, measure: str) -> UnitTest | None:
    a, b = _unit_values(units, method, other, measure)
    if not a.size:
        return None
    better = a < b if measure in LOWER_IS_BETTER else a > b
    return UnitTest(
        measure,
        method,
        other,
        int(a.size),
        paired_diff(a, b),
        wilcoxon_p(a, b),
        float(better.mean()),
        paired_ci(a, b),
        rank_biserial(a, b),
    )


# The comparisons each class's table prints and tests, those whose methods both ran.
CLASS_COMPARISONS: tuple[tuple[str, str], ...] = (
    ("aail_bounded", "sl"),
    ("aail", "sl"),
    ("aail_bounded", "aail"),
    ("aail_bounded", "nail"),
    ("aail_bounded", "jl"),
    ("aail_budget", "sl"),
    ("aail_budget", "aail"),
    ("aail_budget", "aail_bounded"),
)
FAMILY_MEASURES: tuple[str, ...] = ("team", "ego", "others")


def class_family(
    group: UnitGroup,
    comparisons: Sequence[tuple[str, str]] = CLASS_COMPARISONS,
    measures: Sequence[str] = FAMILY_MEASURES,
) -> list[UnitTest]:
    """One class's family: every comparison on every measure that ran in it, Holm-adjusted
    together (comparison by comparison, measures in the given order)."""
    tests = [
        t
        for method, other in comparisons
        for measure in measures
        if (t := group.test(method, other, measure)) is not None
    ]
    return with_holm(tests)


def family_test(
    family: Sequence[UnitTest], method: str, other: str, measure: str
) -> UnitTest | None:
    """The test of (method − other) on `measure` in a family, if it ran."""
    return next(
        (t for t in family if (t.method, t.other, t.measure) == (method, other, measure)), None
    )


def _methods(units: Sequence[Unit]) -> list[str]:
    present = {m for u in units for m in u.by_method}
    return [m for m in PAPER_METHODS if m in present] + sorted(present - set(PAPER_METHODS))


def _row(units: Sequence[Unit], method: str) -> MethodRow:
    having = [u for u in units if method in u.by_method]
    with_sl = [u for u in having if "sl" in u.by_method]
    regrets = np.array([u.regret(method) for u in with_sl]) if with_sl else np.array([np.nan])
    within = [float(u.team_within(method)) for u in with_sl] or [np.nan]
    above = [float(u.by_method[method]["team"] > u.by_method["sl"]["team"]) for u in with_sl]
    return MethodRow(
        method=method,
        n_units=len(having),
        means={m: mean_se([u.by_method[method][m] for u in having]) for m in MEASURES},
        stuck_episodes=sum(u.stuck_episodes[method] for u in having),
        episodes=sum(u.episodes for u in having),
        units_with_stuck=sum(u.stuck_episodes[method] > 0 for u in having),
        regret_median=float(np.median(regrets)),
        regret_mean=float(np.mean(regrets)),
        team_within_share=float(np.mean(within)),
        team_above_share=float(np.mean(above or [np.nan])),
    )


def summarise_group(label: str, units: Sequence[Unit]) -> UnitGroup:
    return UnitGroup(label, tuple(units), {m: _row(units, m) for m in _methods(units)})


GROUP_LABELS = {
    "aligned": "aligned",
    "room_to_help": "aligned, room to help",
    "non_aligned": "non-aligned",
    "mixed": "mixed",
    "five_agents": "five agents",
}


def pair_groups(results: Sequence[CellResult]) -> dict[str, UnitGroup]:
    """Groups keyed by `GROUP_LABELS`' keys; a group with no unit is left out."""
    units = units_of(results)
    members = {
        "aligned": [u for u in units if u.pair_class == "aligned"],
        "room_to_help": [u for u in units if u.room_to_help],
        "non_aligned": [u for u in units if u.pair_class == "non_aligned"],
        "mixed": [u for u in units if u.pair_class == "mixed"],
        "five_agents": [u for u in units if u.pair_class is None],
    }
    return {k: summarise_group(GROUP_LABELS[k], v) for k, v in members.items() if v}


@dataclass(frozen=True)
class ReplicateRow:
    """One replicate's episodes of one class and method: is a result the same across seeds?"""

    replicate: int
    seed: int
    label: str
    method: str
    units: int
    episodes: int
    ego_success: float
    stuck_episodes: int
    team: float


def replicate_rows(results: Sequence[CellResult], base_seed: int) -> list[ReplicateRow]:
    """Per replicate, class and method: success rate, stuck episodes, mean team return."""
    acc: dict[tuple[int, str, str], list[CellResult]] = {}
    for r in results:
        kind: str = r.scenario.pair_class or "five_agents"
        acc.setdefault((r.scenario.replicate, kind, r.method), []).append(r)
    rows = []
    for (rep, kind, method), cells in sorted(acc.items()):
        success = np.concatenate([c.success_EN[:, 0] for c in cells])
        team = np.concatenate([c.team_E for c in cells])
        rows.append(
            ReplicateRow(
                rep,
                base_seed + rep,
                GROUP_LABELS[kind],
                method,
                len(cells),
                int(success.size),
                float(success.mean()),
                int((~success).sum()),
                float(team.mean()),
            )
        )
    return rows
