"""The goal-inference report's figures (matplotlib, Agg backend, PNG).

| function              | file                  | what                                               |
|-----------------------|-----------------------|----------------------------------------------------|
| `plot_accuracy`       | `accuracy_vs_k.png`   | top-1 (Wilson 95 % band) vs k for the server's     |
|                       |                       | default belief and λ = 1; top-3 and nested for the |
|                       |                       | default; a reference run whose partner is driven by|
|                       |                       | the likelihood networks themselves                 |
| `plot_cross_entropy`  | `cross_entropy.png`   | mean -log b_k(g*) ± SE vs k, every floored setting |
| `plot_switch`         | `goal_switch.png`     | top-1 vs k when the partner changes its goal       |
| `plot_value`          | `value.png`           | team / ego / partner return of SL, AAIL announced, |
|                       |                       | AAIL inferred per scenario and pair group          |

The curve functions read `AccuracyResult.summary()` dictionaries (belief label -> series), so
the figures can be redrawn from `results.json` alone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from envs.particle.goals import N_GOALS
from evaluation.figures import save_figure

Series = Mapping[str, Mapping[str, list[float]]]  # belief label -> measure -> per-k values
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")
VALUE_COLOURS = {"sl": "#7f7f7f", "aail": "#1f77b4", "aail-inferred": "#17becf"}
VALUE_LABELS = {"sl": "SL", "aail": "AAIL, goal announced", "aail-inferred": "AAIL, goal inferred"}


def _top1(ax: Any, k: np.ndarray, s: Mapping[str, list[float]], colour: str, label: str) -> None:
    ax.fill_between(k, s["accuracy_lo"], s["accuracy_hi"], color=colour, alpha=0.2)
    ax.plot(k, s["accuracy"], color=colour, label=f"top-1, {label}")


def _finish(ax: Any, episodes: int) -> None:
    ax.axhline(1 / N_GOALS, color="black", linewidth=0.6, linestyle=":", label="chance (1/35)")
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("k (partner actions observed)")
    ax.set_ylabel(f"share of {episodes} episodes")
    ax.grid(alpha=0.3)


def plot_accuracy(
    series: Series, episodes: int, path: Path, reference: Mapping[str, list[float]] | None = None
) -> Path:
    """The first two settings of `series` (default first); `reference`: the matched run."""
    fig, ax = plt.subplots(figsize=(9.6, 4.4))
    for j, (label, s) in enumerate(list(series.items())[:2]):
        k = np.arange(len(s["accuracy"]))
        _top1(ax, k, s, COLOURS[j], label)
        if j == 0:
            ax.plot(k, s["top3"], color=COLOURS[j], linestyle="--", label=f"top-3, {label}")
            ax.plot(
                k,
                s["nested"],
                color=COLOURS[j],
                linestyle="-.",
                label=f"top-1 up to nesting, {label}",
            )
    if reference is not None:
        k = np.arange(len(reference["accuracy"]))
        ax.plot(
            k,
            reference["accuracy"],
            color="#555555",
            linestyle=":",
            linewidth=1.6,
            label="top-1, partner driven by the likelihood nets",
        )
    _finish(ax, episodes)
    ax.set_title("Belief's top goal = the partner's true goal (band: Wilson 95 %)", fontsize=10)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # outside: no overlap
    return save_figure(fig, path)


def _floor(label: str) -> float:
    """ε of a `belief_label` ("λ = 1, ε = 0.001[, α = ...]")."""
    return float(label.split("ε = ")[1].split(",")[0])


def plot_cross_entropy(series: Series, path: Path) -> Path:
    """Every setting with a floor (without one, -log b can grow without bound)."""
    fig, ax = plt.subplots(figsize=(9.6, 4.4))
    for colour, (label, s) in zip(COLOURS, series.items(), strict=False):
        if _floor(label) == 0:
            continue
        k = np.arange(len(s["cross_entropy"]))
        mean, se = np.asarray(s["cross_entropy"]), np.asarray(s["cross_entropy_se"])
        ax.fill_between(k, mean - se, mean + se, color=colour, alpha=0.2)
        ax.plot(k, mean, color=colour, label=label)
    ax.axhline(
        math.log(N_GOALS),
        color="black",
        linewidth=0.6,
        linestyle=":",
        label="uniform belief (log 35)",
    )
    ax.set_xlabel("k (partner actions observed)")
    ax.set_ylabel("mean -log b_k(true goal) [nats]")
    ax.set_title("Cross-entropy of the belief (band: ± SE)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return save_figure(fig, path)


def plot_switch(series: Series, episodes: int, switch_at: int, path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(9.6, 4.4))
    for colour, (label, s) in zip(COLOURS, series.items(), strict=False):
        _top1(ax, np.arange(len(s["accuracy"])), s, colour, label)
    _finish(ax, episodes)
    ax.axvline(switch_at, color="black", linewidth=1.0)
    ax.text(switch_at + 0.5, 0.95, "partner changes its goal", fontsize=8, va="top")
    ax.set_title("Top goal = the partner's current goal, goal changed mid-episode", fontsize=10)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return save_figure(fig, path)


def plot_value(
    panels: Mapping[str, Mapping[str, Mapping[str, tuple[float, float]]]], path: Path
) -> Path:
    """`panels[label][method][measure]` = (mean, SE) for the measures ego, others, team."""
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 3.8), squeeze=False)
    measures = (("ego", "ego"), ("others", "partner"), ("team", "team"))
    for ax, (label, by_method) in zip(axes[0], panels.items(), strict=True):
        width = 0.8 / max(len(by_method), 1)
        x = np.arange(len(measures))
        for j, (method, values) in enumerate(by_method.items()):
            offset = (j - (len(by_method) - 1) / 2) * width
            means = [values[m][0] for m, _ in measures]
            errors = [values[m][1] for m, _ in measures]
            colour, label = VALUE_COLOURS.get(method), VALUE_LABELS.get(method, method)
            ax.bar(x + offset, means, width, yerr=errors, capsize=3, color=colour, label=label)
        ax.set_xticks(x, [name for _, name in measures])
        ax.axhline(0, color="black", linewidth=0.6)
        ax.set_ylabel("accumulated reward")
        ax.set_title(label, fontsize=9)
    axes[0][0].legend(fontsize=7)
    return save_figure(fig, path)
