"""`JobRunner`: one thread that runs the queued training jobs, one subprocess at a time.

    runner = JobRunner(table, store_url="sqlite:////abs/models.db", run_root=Path("/data/jobs"))
    runner.start()        # requeues jobs left running by a dead process, then works the queue
    runner.stop()         # kills the running subprocess and leaves its job for the next process

Each job runs `python -m cli.main train <kind> ... --store-url <store> --run-dir <run_root>/<id>
--resume` (`spec.train_command`), stdout and stderr appended to `<run_dir>/log.txt`. One job at a
time per process: training takes every core there is. The loop wakes every `poll_s` (or at once
on `wake()`), refreshes the running job's heartbeat every `heartbeat_s`, and re-runs `recover`
every `stale_after_s / 2` so a job abandoned by another, dead, process is picked up too.
"""

from __future__ import annotations

import logging
import subprocess
import threading
import time
from pathlib import Path

from trainer.jobs.spec import train_command
from trainer.jobs.table import Job, JobTable

log = logging.getLogger("coexist.jobs")

LOG_NAME = "log.txt"
_PROJECT_ROOT = Path(__file__).resolve().parents[2]  # `-m cli.main` resolves from here


def read_log(run_dir: str | Path, max_chars: int) -> str:
    """The last `max_chars` characters of a job's log ('' before it starts)."""
    file = Path(run_dir) / LOG_NAME
    if not file.exists():
        return ""
    with file.open("rb") as f:
        f.seek(0, 2)
        f.seek(max(0, f.tell() - 4 * max_chars))  # utf-8: at most 4 bytes per character
        return f.read().decode("utf-8", errors="replace")[-max_chars:]


class JobRunner:
    def __init__(
        self,
        table: JobTable,
        *,
        store_url: str,
        poll_s: float = 1.0,
        heartbeat_s: float = 5.0,
    ) -> None:
        self.table, self.store_url = table, store_url
        self.poll_s, self.heartbeat_s = poll_s, heartbeat_s
        self._wake = threading.Event()
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._loop, name="coexist-jobs", daemon=True)
            self._thread.start()

    def wake(self) -> None:
        """A job was submitted: look at the queue now."""
        self._wake.set()

    def stop(self, timeout_s: float = 10.0) -> None:
        self._stopping.set()
        self._wake.set()  # the loop terminates the subprocess itself (see `_run`)
        if self._thread is not None:
            self._thread.join(timeout_s)

    def _loop(self) -> None:
        last_recover = -float("inf")
        while not self._stopping.is_set():
            try:
                if time.monotonic() - last_recover >= self.table.stale_after_s / 2:
                    self.table.recover()
                    last_recover = time.monotonic()
                job = self.table.claim_next()
                if job is not None:
                    self._run(job)
                    continue  # the queue may hold more
            except Exception:  # the database went away: keep the thread alive, try again
                log.exception("job runner: error while working the queue")
            self._wake.wait(self.poll_s)
            self._wake.clear()

    def _run(self, job: Job) -> None:
        run_dir = Path(job.run_dir)
        run_dir.mkdir(parents=True, exist_ok=True)
        cmd = train_command(job.spec, self.store_url, run_dir)
        log.info("job %s: attempt %d: %s", job.id, job.attempts, " ".join(cmd))
        with (run_dir / LOG_NAME).open("ab") as out:
            out.write(f"--- attempt {job.attempts}: {' '.join(cmd)}\n".encode())
            out.flush()
            self._proc = proc = subprocess.Popen(
                cmd, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                cwd=_PROJECT_ROOT,
            )  # fmt: skip
            last_beat = time.monotonic()
            while proc.poll() is None:
                if self._stopping.wait(self.poll_s):
                    proc.terminate()
                    proc.wait()
                    self.table.release(job.id)  # the next process resumes it
                    log.info("job %s: left for the next process", job.id)
                    return
                if time.monotonic() - last_beat >= self.heartbeat_s:
                    self.table.heartbeat(job.id)
                    last_beat = time.monotonic()
        self._proc = None
        self.table.finish(job.id, proc.returncode, read_log(run_dir, 8_000))
        log.info("job %s: exit code %d", job.id, proc.returncode)
