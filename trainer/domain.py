"""What the trainer needs from an environment, and where it finds it.

An environment's registration (`envs.registry.EnvPlugin.training`) names how it trains:

- nothing, or a `trainer.generic.GenericTraining`: the trainer's generic machinery (task and
  impact learners on the env's own PettingZoo env, generic gates) with the env's numbers;
- an object implementing `EnvTrainer`: the learners of the paper (task, impact, and where it
  applies the joint baseline) on rollouts of its own, gated by its own quality gates (a trainer
  without the joint baseline subclasses `EnvTrainer`, sets `no_joint_reason` and inherits
  `train_joint`'s refusal). The particle world and the kitchen do this (`trainer/particle/`,
  `trainer/cooking/`): batched worlds and scripted references make them faster and stricter.

`trainer.zoo`, `trainer.learners`, the job backends and the CLI reach an environment only
through `trainer.plugins.env_trainer(name)`, so a new environment needs nothing in the trainer.

A configuration names its environment (`SoftQConfig.env_name()`), so `trainer.learners.train_tasks`
and its siblings dispatch on the configuration they are given.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Protocol

from policy.qnet import QNetSpec, StackedQNet
from trainer.config import SoftQConfig
from trainer.loop import TrainingCurves

if TYPE_CHECKING:
    from trainer.loop import ProgressFn


class Gate(Protocol):
    """The quality gate of one trained network (its fields go to the registry as metrics)."""

    @property
    def goal(self) -> str: ...

    @property
    def passed(self) -> bool: ...

    FAILURE_NOTE: ClassVar[str]
    """Printed under the summary when a gate of this kind failed ("" for none)."""

    def metrics(self) -> dict[str, Any]: ...

    def summary_cells(self) -> list[str]:
        """The success, return and reference cells of the training summary table."""
        ...


class EnvTrainer(Protocol):
    """The learners of one environment (paper §3.1-3.2), each training a batch of networks."""

    no_joint_reason: str
    """Why the environment has no joint-learner baseline ("" where it has one)."""
    production_parents_only: bool
    """Whether an impact network may only learn beside a `production` task network (one that
    passed its gate), or may fall back to `latest` (`trainer.zoo`). A trainer may also have
    `monitor_states`, a `trainer.monitor.StateSampler`: where it does (the particle world),
    `coexist train monitor` trains the environment's goal monitors, on the labels of its
    `monitor_labels` (a `trainer.monitor.Labeller`) where it has one."""

    def default_configs(self) -> tuple[SoftQConfig, SoftQConfig]:
        """The task and the impact learner's configuration."""
        ...

    def train_tasks(
        self,
        goals: Sequence[str],
        config: Any,
        *,
        seed: int,
        progress: ProgressFn | None,
        evaluate: bool,
    ) -> TrainedBatch: ...

    def train_impacts(
        self,
        partner_goals: Sequence[str],
        partner_task_nets: StackedQNet,
        config: Any,
        *,
        seed: int,
        progress: ProgressFn | None,
        evaluate: bool,
    ) -> TrainedBatch: ...

    def train_joint(
        self,
        combos: Sequence[Sequence[str]],
        partner_task_nets: Sequence[StackedQNet],
        config: Any,
        *,
        seed: int,
        progress: ProgressFn | None,
        ego_task_nets: StackedQNet | None = None,
    ) -> TrainedBatch:
        """The joint-learner baseline, gated against `ego_task_nets` (each combination's ego's
        task network) where given; ValueError(`no_joint_reason`) where there is none: the
        default, which a trainer without the baseline inherits by subclassing `EnvTrainer`."""
        raise ValueError(self.no_joint_reason)

    def print_gates(self, batches: Sequence[TrainedBatch], console: Any = None) -> None:
        """Gate details beyond the summary table (nothing where the table says it all)."""
        ...


Kind = Literal["task", "impact", "joint"]


@dataclass
class TrainedBatch:
    """G networks trained together; member g belongs to `goals[g]` (a combination for joint)."""

    kind: Kind
    goals: list[tuple[str, ...]]
    nets: StackedQNet
    spec: QNetSpec
    config: SoftQConfig
    seed: int
    curves: TrainingCurves
    gates: Sequence[Gate | None] = field(default_factory=list)

    def gate_passed(self, g: int) -> bool | None:
        gate = self.gates[g] if self.gates else None
        return None if gate is None else gate.passed

    def curve_summary(self, g: int) -> dict[str, Any]:
        """Start, best and final mean episode return of member g (the full curve goes to plots)."""
        series = [row[g] for row in self.curves.returns_G]
        if not series:
            return {}
        return {
            "first": series[0],
            "best": max(series),
            "final": series[-1],
            "points": len(series),
            "steps": self.curves.steps[-1],
        }

    def curve_series(self, g: int) -> dict[str, list[int] | list[float]]:
        """Member g's whole training curve (registered with its version, drawn by the web
        console): the training step of each point, the mean return of the episodes that ended
        since the point before, and the mean loss of the updates since then."""
        return {
            "steps": list(self.curves.steps),
            "mean_return": [row[g] for row in self.curves.returns_G],
            "loss": [row[g] for row in self.curves.losses_G],
        }
