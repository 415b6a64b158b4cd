"""Human-facing output of a training run: a summary table and training-curve plots (paper Fig. 4)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from trainer.cooking_gates import CookingImpactGate, CookingTaskGate
from trainer.gates import ImpactGate, TaskGate
from trainer.learners import TrainedBatch

KITCHEN_NOTE = (
    "A cooking task network that failed its gate gets no `production` alias, and in the kitchen "
    "impact networks train only against `production` task networks (trainer.zoo): its goal gets "
    "no impact network until a task network passes (then `coexist train impact --env cooking`)."
)


def print_summary(batches: Sequence[TrainedBatch], console: Console | None = None) -> None:
    """One row per network: its gate verdict and the numbers behind it (the kitchen's gates:
    dish completion rates, steps to the dish and unshaped returns)."""
    console = console or Console()
    if not batches:
        console.print("nothing to train: every batch of this run is already done (--resume)")
        return
    table = Table(title="trained networks")
    for col in ("kind", "goal(s)", "gate", "success", "return", "reference", "final train return"):
        table.add_column(col, justify="left" if col in ("kind", "goal(s)", "gate") else "right")
    for batch in batches:
        for g, goals in enumerate(batch.goals):
            gate = batch.gates[g] if batch.gates else None
            final = batch.curve_summary(g).get("final")
            cells = ["-", "-", "-", "-"]
            if isinstance(gate, TaskGate):
                cells = [
                    _verdict(gate.passed),
                    f"{gate.success_rate:.0%}",
                    f"{gate.own_target_return:.2f} (own target)",
                    f"{gate.scripted_own_target_return:.2f} (scripted)",
                ]
            elif isinstance(gate, ImpactGate):
                dead = f", dead: {'/'.join(gate.dead_pushes)}" if gate.dead_pushes else ""
                cells = [
                    _verdict(gate.passed),
                    f"{gate.toward_share:.0%} toward{dead}",
                    f"{gate.partner_return:.2f} (partner)",
                    f"{gate.partner_return_resting_ego:.2f} (resting ego)",
                ]
            if isinstance(gate, CookingTaskGate | CookingImpactGate):
                cells = _kitchen_cells(gate)
            table.add_row(
                batch.kind, "+".join(goals), *cells, "-" if final is None else f"{final:.3f}"
            )
    console.print(table)
    if any(isinstance(g, CookingTaskGate) and not g.passed for b in batches for g in b.gates):
        console.print(KITCHEN_NOTE)


def _kitchen_cells(gate: CookingTaskGate | CookingImpactGate) -> list[str]:
    """Gate, success (dish completion), return and reference cells of a cooking gate."""
    if isinstance(gate, CookingTaskGate):
        return [
            _verdict(gate.passed),
            f"{gate.completion_rate:.0%} in {_steps(gate.mean_steps_to_dish)}",
            f"{gate.mean_return:.2f} (own)",
            f"{gate.scripted_completion_rate:.0%} in "
            f"{_steps(gate.scripted_mean_steps_to_dish)} (scripted)",
        ]
    return [
        _verdict(gate.passed),
        f"{gate.partner_completion_rate:.0%}",
        f"{gate.partner_return:.2f} (partner)",
        f"{gate.partner_completion_rate_resting_ego:.0%} (resting ego)",
    ]


def _steps(steps: float | None) -> str:
    return "-" if steps is None else f"{steps:.0f} st"


def _verdict(passed: bool) -> str:
    return "[green]passed[/green]" if passed else "[red]failed[/red]"


def write_curves(batches: Sequence[TrainedBatch], out_dir: Path) -> list[Path]:
    """Mean ± std of the training return over the networks of each kind, one PNG per kind."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for kind in ("task", "impact", "joint"):
        series = [b for b in batches if b.kind == kind and b.curves.returns_G]
        if not series:
            continue
        fig, ax = plt.subplots(figsize=(6, 3.5))
        for batch in series:
            steps = np.asarray(batch.curves.steps) * batch.config.envs_per_net
            returns = np.asarray(batch.curves.returns_G)
            mean, std = returns.mean(axis=1), returns.std(axis=1)
            label = f"{len(batch.goals)} networks"
            ax.plot(steps, mean, label=label)
            ax.fill_between(steps, mean - std, mean + std, alpha=0.25)
        ax.set_xlabel("environment steps per network")
        ax.set_ylabel("episode return" if kind != "impact" else "episode impact reward")
        ax.set_title(f"{kind} learning (mean ± std over networks)")
        ax.legend(loc="lower right")
        fig.tight_layout()
        out_dir.mkdir(parents=True, exist_ok=True)
        path = out_dir / f"curves_{kind}.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)
    return written
