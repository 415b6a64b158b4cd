"""Human-facing output of a training run: a summary table and training-curve plots (paper Fig. 4)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from trainer.learners import TrainedBatch


def print_summary(batches: Sequence[TrainedBatch], console: Console | None = None) -> None:
    """One row per network: its gate verdict and the numbers behind it (each gate's
    `summary_cells`; the kitchen's: dish completion rates, steps to the dish, unshaped returns)."""
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
            if gate is not None:
                cells = [_verdict(gate.passed), *gate.summary_cells()]
            table.add_row(
                batch.kind, "+".join(goals), *cells, "-" if final is None else f"{final:.3f}"
            )
    console.print(table)
    notes = {g.FAILURE_NOTE for b in batches for g in b.gates if g is not None and not g.passed}
    for note in sorted(notes - {""}):
        console.print(note)


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
