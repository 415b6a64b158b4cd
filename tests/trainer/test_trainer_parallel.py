"""Batches trained in worker processes are the batches trained one after the other."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import pytest
import torch

from trainer.config import TaskConfig
from trainer.learners import train_tasks
from trainer.parallel import BatchJob, train_batches

CONFIG = replace(
    TaskConfig(), hidden=(16,), total_steps=60, warmup_steps=10, envs_per_net=4, eval_episodes=4
)


def _jobs() -> list[BatchJob]:
    return [
        BatchJob(f"task {i}", CONFIG.total_steps, train_tasks, (goals, CONFIG), {"seed": 3 + i})
        for i, goals in enumerate((["a2", "b3"], ["c4"]))
    ]


@pytest.mark.slow
def test_two_workers_train_the_same_networks_and_report_every_step() -> None:
    seen: dict[str, list[int]] = {}

    def progress(label: str, total: int) -> Callable[[int, int], None]:
        seen[label] = []
        return lambda done, _total: seen[label].append(done)

    alone = list(train_batches(_jobs(), workers=1, progress=lambda label, total: lambda d, t: None))
    beside = list(train_batches(_jobs(), workers=2, progress=progress))
    assert [b.goals for b in beside] == [[("a2",), ("b3",)], [("c4",)]]
    for a, b in zip(alone, beside, strict=True):
        for (name, x), y in zip(
            a.nets.state_dict().items(), b.nets.state_dict().values(), strict=True
        ):
            assert torch.equal(x, y), name
        assert [a.gate_passed(g) for g in range(len(a.goals))] == [
            b.gate_passed(g) for g in range(len(b.goals))
        ]
        assert a.curves.returns_G == b.curves.returns_G
    assert seen == {"task 0": list(range(1, 61)), "task 1": list(range(1, 61))}


@pytest.mark.slow
def test_a_failing_worker_raises_in_the_parent() -> None:
    bad = BatchJob("task x", 10, train_tasks, (["zz"], CONFIG), {"seed": 0})
    with pytest.raises(ValueError, match="zz"):
        list(
            train_batches(
                [_jobs()[1], bad], workers=2, progress=lambda label, total: lambda d, t: None
            )
        )


def test_workers_must_be_positive() -> None:
    with pytest.raises(ValueError, match="workers"):
        list(train_batches(_jobs(), workers=0, progress=lambda label, total: lambda d, t: None))
