"""The report's figures (matplotlib, Agg backend, PNG).

| function              | paper    | what                                                        |
|-----------------------|----------|-------------------------------------------------------------|
| `plot_returns`        | Figs 5, 7| bars per method: each agent's return and the team's, ± SE   |
| `plot_pairs`          | (ours)   | goal pairs per strict class and goal sets: each unit's team |
|                       |          | return minus SL's, and the stuck episodes per method        |
| `plot_directions`     | Fig. 6   | quiver of the expected acceleration over ego positions      |
| `plot_training`       | Fig. 4   | training returns from the lineage's curve summaries         |
| `plot_episode_strip`  |          | rendered frames of one episode, one row per method          |
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Rectangle

from envs.particle.goals import INFLUENCE_BOXES_G4, TARGET_BOXES_G4, goal_index
from envs.particle.render import render_frame
from evaluation.config import METHOD_LABELS, Scenario
from evaluation.figures import save_figure
from evaluation.paper.directions import DirectionField
from evaluation.paper.pairs import UnitGroup
from evaluation.stats import MethodSummary

SYMLOG_RATIO = 30.0  # largest / smallest bar beyond which the y axis is symlog
COLOURS = {
    "sl": "#7f7f7f",
    "nail": "#ff7f0e",
    "aail": "#1f77b4",
    "aail_bounded": "#9467bd",
    "jl": "#2ca02c",
}


def _bars(
    ax: Any, groups: Sequence[str], series: Mapping[str, Sequence[tuple[float, float]]]
) -> None:
    width = 0.8 / max(len(series), 1)
    x = np.arange(len(groups))
    for k, (method, values) in enumerate(series.items()):
        means = [v[0] for v in values]
        errors = [v[1] for v in values]
        ax.bar(
            x + (k - (len(series) - 1) / 2) * width,
            means,
            width,
            yerr=errors,
            capsize=3,
            label=METHOD_LABELS.get(method, method),
            color=COLOURS.get(method),
        )
    ax.set_xticks(x, groups)
    ax.axhline(0, color="black", linewidth=0.6)
    magnitudes = [abs(v[0]) for values in series.values() for v in values if v[0] != 0]
    if magnitudes and max(magnitudes) > SYMLOG_RATIO * min(magnitudes):
        # one method far below the others would flatten every other bar on a linear axis
        ax.set_yscale("symlog", linthresh=max(min(magnitudes), 1e-3))
        ax.set_ylabel("accumulated reward (symlog)")
    else:
        ax.set_ylabel("accumulated reward")


def plot_returns(
    panels: Sequence[tuple[Scenario, Sequence[MethodSummary]]], path: Path, title: str
) -> Path:
    """One panel per scenario; groups = ego, each partner, team (mean ± SE over episodes)."""
    width = max(5.2, 1.3 * (2 + max(len(s.partner_goals) for s, _ in panels)))
    fig, axes = plt.subplots(1, len(panels), figsize=(width * len(panels), 3.8), squeeze=False)
    for ax, (scenario, summaries) in zip(axes[0], panels, strict=True):
        groups = (
            [f"agent 1 ({scenario.ego_goal})"]
            + [f"agent {j + 2} ({g})" for j, g in enumerate(scenario.partner_goals)]
            + ["team"]
        )
        series = {
            s.method: [(s.ego.mean, s.ego.se)]
            + [(p.mean, p.se) for p in s.per_partner]
            + [(s.team.mean, s.team.se)]
            for s in summaries
        }
        _bars(ax, groups, series)
        ax.set_title(f"{scenario.name}: {scenario.combo} ({summaries[0].episodes} episodes)")
        ax.tick_params(axis="x", labelsize=8)
    axes[0][0].legend(fontsize=8)
    fig.suptitle(title)
    return save_figure(fig, path)


def plot_pairs(groups: Sequence[UnitGroup], path: Path) -> Path:
    """Top: each unit's team return minus SL's, one column of dots per method (symlog);
    bottom: the share of episodes that ended with the ego outside its target (stuck)."""
    fig, axes = plt.subplots(2, len(groups), figsize=(4.2 * len(groups), 6.4), squeeze=False)
    rng = np.random.default_rng(0)  # jitter only
    for k, group in enumerate(groups):
        methods = [m for m in group.rows if m != "sl"]
        top, bottom = axes[0][k], axes[1][k]
        for x, method in enumerate(methods):
            diffs = [
                u.by_method[method]["team"] - u.by_method["sl"]["team"]
                for u in group.units
                if method in u.by_method and "sl" in u.by_method
            ]
            jitter = rng.uniform(-0.18, 0.18, len(diffs))
            top.scatter(x + jitter, diffs, s=9, alpha=0.7, color=COLOURS.get(method))
        top.axhline(0, color="black", linewidth=0.6)
        top.set_yscale("symlog", linthresh=1.0)
        top.set_xticks(range(len(methods)), [METHOD_LABELS.get(m, m) for m in methods])
        top.set_title(f"{group.label} ({len(group.units)})", fontsize=9)
        shares = [group.rows[m].stuck_episodes / max(group.rows[m].episodes, 1) for m in group.rows]
        names = [METHOD_LABELS.get(m, m) for m in group.rows]
        bars = bottom.bar(names, shares, color=[COLOURS.get(m) for m in group.rows])
        for bar, method in zip(bars, group.rows, strict=True):
            bottom.annotate(
                str(group.rows[method].stuck_episodes),
                (bar.get_x(), bar.get_height()),
                fontsize=7,
                xytext=(1, 2),
                textcoords="offset points",
            )
        bottom.set_ylim(0, 1)
        bottom.tick_params(axis="x", labelsize=8)
    axes[0][0].set_ylabel("team return − SL's, per unit")
    axes[1][0].set_ylabel("stuck episodes (share; count on the bar)")
    return save_figure(fig, path)


def _box(ax: Any, box: np.ndarray, colour: str, filled: bool, label: str) -> None:
    x_lo, x_hi, y_lo, y_hi = (float(v) for v in box)
    ax.add_patch(
        Rectangle(
            (x_lo, y_lo),
            x_hi - x_lo,
            y_hi - y_lo,
            fill=filled,
            alpha=0.25 if filled else 1.0,
            color=colour,
            linewidth=2,
            label=label,
        )
    )


def plot_directions(
    fields: Sequence[DirectionField],
    ego_goal: str,
    partner_goal: str,
    partner_xy: tuple[float, float],
    path: Path,
) -> Path:
    fig, axes = plt.subplots(1, len(fields), figsize=(3.6 * len(fields), 3.8), squeeze=False)
    for ax, field in zip(axes[0], fields, strict=True):
        _box(ax, TARGET_BOXES_G4[goal_index(ego_goal)], "#1f77b4", True, f"ego target {ego_goal}")
        _box(
            ax,
            INFLUENCE_BOXES_G4[goal_index(partner_goal)],
            "#d62728",
            False,
            f"partner {partner_goal} influence",
        )
        _box(
            ax,
            TARGET_BOXES_G4[goal_index(partner_goal)],
            "#d62728",
            True,
            f"partner target {partner_goal}",
        )
        p, a = field.positions_B2, field.accel_B2
        spacing = 1.0 / np.sqrt(len(p))  # a unit-length mean acceleration spans 80 % of a cell
        ax.quiver(
            p[:, 0],
            p[:, 1],
            a[:, 0],
            a[:, 1],
            angles="xy",
            scale_units="xy",
            scale=1.25 / spacing,
            width=0.005,
        )
        ax.plot(*partner_xy, "o", color="#d62728", markersize=9, markeredgecolor="black")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_aspect("equal")
        ax.set_title(field.label)
        ax.set_xticks([0, 0.2, 0.4, 0.6, 0.8, 1.0])
        ax.set_yticks([0, 0.2, 0.4, 0.6, 0.8, 1.0])
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=6, loc="lower left")
    return save_figure(fig, path)


def plot_training(curves: Mapping[str, Sequence[Mapping[str, float]]], path: Path) -> Path:
    """Per kind: every network's training return at its first and last log point (lines) and
    the mean ± std over networks; `curves[kind]` are the lineage `metrics.curve` summaries."""
    kinds = [k for k in ("task", "impact", "joint") if curves.get(k)]
    fig, axes = plt.subplots(
        1, max(len(kinds), 1), figsize=(4.2 * max(len(kinds), 1), 3.4), squeeze=False
    )
    for ax, kind in zip(axes[0], kinds, strict=False):
        rows = [c for c in curves[kind] if {"first", "final", "steps"} <= set(c)]
        for c in rows:
            ax.plot([0, c["steps"]], [c["first"], c["final"]], color="#bbbbbb", linewidth=0.7)
        if rows:
            steps = float(np.mean([c["steps"] for c in rows]))
            for x, key in ((0.0, "first"), (steps, "final")):
                values = np.array([c[key] for c in rows])
                ax.errorbar(
                    x, values.mean(), yerr=values.std(), fmt="o", color="#1f77b4", capsize=4
                )
        ax.set_title(f"{kind} ({len(rows)} networks)")
        ax.set_xlabel("batched training steps")
        ax.set_ylabel("mean episode return" if kind != "impact" else "mean impact return")
    return save_figure(fig, path)


def plot_episode_strip(
    trajectories: Mapping[str, np.ndarray], goals: Sequence[str], path: Path, frames: int = 8
) -> Path:
    """Rows = methods, columns = `frames` evenly spaced steps of each method's episode."""
    methods = list(trajectories)
    fig, axes = plt.subplots(
        len(methods), frames, figsize=(1.6 * frames, 1.75 * len(methods)), squeeze=False
    )
    for row, method in enumerate(methods):
        states = trajectories[method]
        picks = np.unique(np.linspace(0, len(states) - 1, frames).round().astype(int))
        for col in range(frames):
            ax = axes[row][col]
            ax.axis("off")
            if col < len(picks):
                ax.imshow(render_frame(states[picks[col]], goals, size=160))
                ax.set_title(f"t = {picks[col]}", fontsize=7)
        axes[row][0].text(
            -0.08,
            0.5,
            METHOD_LABELS.get(method, method),
            rotation=90,
            transform=axes[row][0].transAxes,
            va="center",
            ha="right",
        )
    return save_figure(fig, path)
