"""Statistics of paired episodes: mean ± standard error, Wilcoxon signed-rank, exact McNemar.

| function          | what                                                                    |
|-------------------|-------------------------------------------------------------------------|
| `mean_se`         | mean and standard error (sample std / sqrt(n)) — `services.env_client`'s|
| `wilcoxon_p`      | two-sided Wilcoxon signed-rank p of paired samples (scipy); 1 when every|
|                   | difference is 0 (nothing to rank), NaN-free                             |
| `mcnemar_p`       | two-sided exact McNemar p of paired successes (binomial test on the     |
|                   | discordant pairs); 1 when there are none                                |
| `paired_diff`     | mean ± SE of the paired differences a - b                               |
| `summarise_cell`  | one method's row of a scenario table                                    |
| `compare_cells`   | AAIL (or any method) against another on the same episodes               |

Success is binary, so its paired test is McNemar's, not Wilcoxon's (a signed-rank test on 0/±1
differences is a sign test with a normal approximation); every other measure uses Wilcoxon with
scipy's defaults (zero differences dropped, exact distribution for small samples without ties).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from evaluation.rollout import CellResult
from services.env_client import MeanSE, mean_se

__all__ = [
    "MeanSE",
    "MethodSummary",
    "PairedTest",
    "compare_cells",
    "mcnemar_p",
    "mean_se",
    "paired_diff",
    "summarise_cell",
    "wilcoxon_p",
]


def _paired(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> np.ndarray:
    a_n, b_n = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a_n.ndim != 1 or a_n.shape != b_n.shape or a_n.size == 0:
        raise ValueError(
            f"paired samples: expected two 1-d arrays of one non-zero length, got shapes "
            f"{a_n.shape} and {b_n.shape}"
        )
    if not (np.isfinite(a_n).all() and np.isfinite(b_n).all()):
        raise ValueError("paired samples: expected finite values")
    return a_n - b_n


def wilcoxon_p(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> float:
    """Two-sided Wilcoxon signed-rank p-value of the paired samples a and b."""
    diff = _paired(a, b)
    if not np.any(diff != 0.0):
        return 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # one non-zero difference: se = 0
        p = float(sps.wilcoxon(diff).pvalue)
    return p if math.isfinite(p) else 1.0


def mcnemar_p(a: Sequence[bool] | np.ndarray, b: Sequence[bool] | np.ndarray) -> float:
    """Two-sided exact McNemar p-value of paired binary outcomes a and b."""
    a_n, b_n = np.asarray(a, dtype=bool), np.asarray(b, dtype=bool)
    _paired(a_n.astype(float), b_n.astype(float))
    only_a = int(np.sum(a_n & ~b_n))
    only_b = int(np.sum(~a_n & b_n))
    if only_a + only_b == 0:
        return 1.0
    return float(sps.binomtest(only_a, only_a + only_b, 0.5).pvalue)


def paired_diff(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> MeanSE:
    """Mean ± standard error of the paired differences a - b."""
    return mean_se(_paired(a, b).tolist())


@dataclass(frozen=True)
class MethodSummary:
    """One method in one scenario: means ± SE over its episodes."""

    method: str
    episodes: int
    ego: MeanSE  # the controlled agent's return
    others: MeanSE  # the sum of the partners' returns
    per_partner: tuple[MeanSE, ...]
    team: MeanSE  # the sum over every agent
    ego_success: float  # share of episodes ending with the ego inside its target
    ego_reached: float  # share in which the ego was inside its target at some step
    partner_success: float  # share of (episode, partner) ending inside the partner's target
    solved: float  # share ended by termination (all agents inside at one step)
    length: MeanSE


def summarise_cell(result: CellResult) -> MethodSummary:
    returns = result.returns_EN
    return MethodSummary(
        method=result.method,
        episodes=int(returns.shape[0]),
        ego=mean_se(returns[:, 0].tolist()),
        others=mean_se(returns[:, 1:].sum(axis=1).tolist()),
        per_partner=tuple(mean_se(returns[:, j].tolist()) for j in range(1, returns.shape[1])),
        team=mean_se(result.team_E.tolist()),
        ego_success=float(result.success_EN[:, 0].mean()),
        ego_reached=float(result.reached_EN[:, 0].mean()),
        partner_success=float(result.success_EN[:, 1:].mean()),
        solved=float(result.solved_E.mean()),
        length=mean_se(result.length_E.astype(float).tolist()),
    )


@dataclass(frozen=True)
class PairedTest:
    """`method` against `other` on one measure over the same n paired units."""

    measure: str
    method: str
    other: str
    n: int
    diff: MeanSE  # mean of (method - other)
    p: float
    test: str  # "wilcoxon" or "mcnemar"


def compare_cells(a: CellResult, b: CellResult) -> list[PairedTest]:
    """Paired tests of a against b (same scenario, same episodes) on every measure."""
    if a.scenario != b.scenario:
        raise ValueError(f"compare_cells: scenarios differ ({a.scenario.name}, {b.scenario.name})")
    measures = {
        "ego return": (a.returns_EN[:, 0], b.returns_EN[:, 0]),
        "others' return": (a.returns_EN[:, 1:].sum(axis=1), b.returns_EN[:, 1:].sum(axis=1)),
        "team return": (a.team_E, b.team_E),
        "length": (a.length_E.astype(float), b.length_E.astype(float)),
    }
    n = int(a.returns_EN.shape[0])
    tests = [
        PairedTest(name, a.method, b.method, n, paired_diff(x, y), wilcoxon_p(x, y), "wilcoxon")
        for name, (x, y) in measures.items()
    ]
    success_a, success_b = a.success_EN[:, 0], b.success_EN[:, 0]
    tests.append(
        PairedTest(
            "ego success",
            a.method,
            b.method,
            n,
            paired_diff(success_a.astype(float), success_b.astype(float)),
            mcnemar_p(success_a, success_b),
            "mcnemar",
        )
    )
    return tests
