"""Batches of goals trained side by side in worker processes, one per core.

A batch of G stacked networks keeps one core busy (`trainer.soft_q`); torch's intra-op threads
do not help at these sizes, so a second core is used by training a second batch of goals in a
second process. Each batch owns its seed, rollouts and generator, so a batch's networks are the
same whether it trains alone, in this process, or beside another one: `workers` changes the
wall time only, never the result. Results come back in the order of the jobs, so the registry
gets the same versions in the same order as a sequential run.

Workers are started with `spawn` (a fresh interpreter: no inherited torch thread pools or
locks) and report progress through a queue that the parent turns into its progress bars.
"""

from __future__ import annotations

import multiprocessing as mp
import queue
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from trainer.learners import TrainedBatch
from trainer.loop import ProgressFactory, ProgressFn


@dataclass(frozen=True)
class BatchJob:
    """One batch to train: `train(*args, progress=..., **kwargs)` returns its `TrainedBatch`.

    `train` must be a module-level function (it is sent to a worker process by reference)."""

    label: str
    total_steps: int
    train: Callable[..., TrainedBatch]
    args: tuple[Any, ...]
    kwargs: dict[str, Any] = field(default_factory=dict)

    def run(self, progress: ProgressFn | None) -> TrainedBatch:
        return self.train(*self.args, progress=progress, **self.kwargs)


def train_batches(
    jobs: Sequence[BatchJob], *, workers: int, progress: ProgressFactory
) -> Iterator[TrainedBatch]:
    """Train every job, at most `workers` at a time; yields the batches in the order of `jobs`,
    each as soon as it and the jobs before it are done (so the caller can register it)."""
    if workers < 1:
        raise ValueError(f"workers: expected at least 1, got {workers}")
    if workers == 1 or len(jobs) <= 1:
        for job in jobs:
            yield job.run(progress(job.label, job.total_steps))
        return
    bars = _Bars([progress(job.label, job.total_steps) for job in jobs])
    context = mp.get_context("spawn")
    reports: Any = context.Queue()
    with ProcessPoolExecutor(
        max_workers=min(workers, len(jobs)),
        mp_context=context,
        initializer=_start_worker,
        initargs=(reports,),
    ) as pool:
        futures = [pool.submit(_run_in_worker, i, job) for i, job in enumerate(jobs)]
        for i, future in enumerate(futures):
            while not future.done():
                bars.forward(reports, timeout=0.2)
            batch = future.result()  # a worker's exception is raised here
            # the last report may still be in the queue's pipe when the result is back
            patience = 25
            while bars.done[i] < jobs[i].total_steps and patience:
                bars.forward(reports, timeout=0.2)
                patience -= 1
            yield batch


class _Bars:
    """The parent's progress callbacks, fed with the workers' (job, done, total) reports."""

    def __init__(self, advance: list[ProgressFn]) -> None:
        self.advance = advance
        self.done = [0] * len(advance)

    def forward(self, reports: Any, *, timeout: float) -> None:
        """Pass on every pending report, waiting up to `timeout` for the first."""
        try:
            job, done, total = reports.get(timeout=timeout)
            while True:
                self.advance[job](done, total)
                self.done[job] = done
                job, done, total = reports.get_nowait()
        except queue.Empty:
            return


_reports: Any = None  # the worker's end of the progress queue (set by `_start_worker`)


def _start_worker(reports: Any) -> None:
    global _reports
    _reports = reports


def _run_in_worker(index: int, job: BatchJob) -> TrainedBatch:
    def report(done: int, total: int) -> None:
        _reports.put((index, done, total))

    return job.run(report)
