"""`JobRunner`: one thread that runs the queued training jobs, one subprocess at a time.

    runner = JobRunner(table, store_url="sqlite:////abs/models.db")  # run dirs: the rows' own
    runner = JobRunner(table, store_url="postgresql://u@db/x", store_password=...)  # PostgreSQL
    runner.start()        # requeues jobs left running by a dead process, then works the queue
    runner.stop()         # stops the running subprocess and leaves its job for the next process

Each job runs `python -m cli.main train <kind> ... --run-dir <run_root>/<id> --resume`
(`spec.train_command`), stdout and stderr appended to `<run_dir>/log.txt`. The store reaches the
trainer only in its environment (readable by the same user and root, unlike the command line,
which every user sees in `ps` and which the job's log repeats): its URL without the password in
`COEXIST_STORE_URL` (`ModelStore.reopen_url`), the database's password apart in `PGPASSWORD`
(`ModelStore.reopen_password`), so that no string holds both. One job at a
time per process: training takes every core there is. The loop wakes every `poll_s` (or at once
on `wake()`), refreshes the running job's heartbeat every `heartbeat_s`, and re-runs `recover`
every `stale_after_s / 2` so a job abandoned by another, dead, process is picked up too.

One trainer per job, whatever dies (`trainer.jobs.leash`): the trainer is started on a leash, so
it dies with this server process (even on `kill -9`) and holds the run directory's lock while it
lives; before an attempt starts, a trainer of an earlier attempt still holding the directory is
stopped (and the job's log says so). The heartbeat is a lease (`trainer.jobs.table`): when it
cannot be renewed, because the job was taken over or because the database stayed out of reach
for `stale_after_s - heartbeat_s`, the runner stops its trainer rather than let two train.

While a job runs, every poll also reads its row: `cancelling` (set by `JobTable.cancel`, from any
server process) makes the runner stop the subprocess (`terminate`: SIGTERM to its process group,
SIGKILL after `cancel_grace_s`), say so in the log and record the job `cancelled` with the exit
code. The subprocess gets a session of its own, so a Ctrl-C meant for the server does not reach it
(the server's shutdown stops it and leaves the job for the next start instead) and the group
signal also reaches anything it started.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from trainer.jobs.leash import leashed, stop_leftover
from trainer.jobs.spec import JobSpec, train_command
from trainer.jobs.table import Job, JobStatus, JobTable

log = logging.getLogger("coexist.jobs")

LOG_NAME = "log.txt"
_PROJECT_ROOT = Path(__file__).resolve().parents[2]  # `-m cli.main` resolves from here

# (spec, run directory) -> argv; tests swap in a stand-in for `coexist train`
CommandFn = Callable[[JobSpec, Path], list[str]]
STORE_URL_ENV = "COEXIST_STORE_URL"  # how the trainer learns the store (`default_store_url`)
# The store's password, apart from its URL. libpq reads this variable for every connection whose
# conninfo has no password, so the trainer's store (and its publish lock) connect with it without
# a line of ours, and a printed or logged COEXIST_STORE_URL holds no secret. SQLite has none.
STORE_PASSWORD_ENV = "PGPASSWORD"


def read_log(run_dir: str | Path, max_chars: int) -> str:
    """The last `max_chars` characters of a job's log ('' before it starts)."""
    file = Path(run_dir) / LOG_NAME
    if not file.exists():
        return ""
    with file.open("rb") as f:
        f.seek(0, 2)
        f.seek(max(0, f.tell() - 4 * max_chars))  # utf-8: at most 4 bytes per character
        return f.read().decode("utf-8", errors="replace")[-max_chars:]


def read_log_from(run_dir: str | Path, offset: int, max_bytes: int) -> tuple[str, int] | None:
    """The log from byte `offset` on (at most `max_bytes`) and the offset after it; None when
    this machine has no log file. A chunk never ends inside a UTF-8 character, so a follower
    that asks again from the returned offset decodes every character whole."""
    file = Path(run_dir) / LOG_NAME
    if not file.exists():
        return None
    with file.open("rb") as f:
        if offset >= os.fstat(f.fileno()).st_size:  # past the end (seek would refuse a huge one)
            return "", offset
        f.seek(offset)
        data = f.read(max_bytes)
    cut = len(data) - _incomplete_tail(data)
    return data[:cut].decode("utf-8", errors="replace"), offset + cut


def _incomplete_tail(data: bytes) -> int:
    """How many bytes at the end of `data` start a UTF-8 character that is not all there."""
    for back in range(1, min(4, len(data)) + 1):
        byte = data[-back]
        if byte & 0xC0 != 0x80:  # a lead byte (or ASCII): how long is its character?
            length = 1 if byte < 0x80 else 2 if byte < 0xE0 else 3 if byte < 0xF0 else 4
            return back if length > back else 0
    return 0


def append_log(run_dir: str | Path, line: str) -> None:
    """Add a line of the runner's own to a job's log, when this machine has the log."""
    file = Path(run_dir) / LOG_NAME
    if file.exists():
        with file.open("ab") as f:
            f.write(f"{line}\n".encode())


class JobRunner:
    def __init__(
        self,
        table: JobTable,
        *,
        store_url: str,
        store_password: str | None = None,
        poll_s: float = 1.0,
        heartbeat_s: float = 5.0,
        cancel_grace_s: float = 10.0,
        command: CommandFn = train_command,
    ) -> None:
        self.table, self.store_url = table, store_url
        self._store_env = {STORE_URL_ENV: store_url}
        if store_password is not None:
            self._store_env[STORE_PASSWORD_ENV] = store_password
        self.poll_s, self.heartbeat_s = poll_s, heartbeat_s
        self.cancel_grace_s, self.command = cancel_grace_s, command
        self._wake = threading.Event()
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._loop, name="coexist-jobs", daemon=True)
            self._thread.start()

    def wake(self) -> None:
        """A job was submitted or cancelled: look at the queue (and the running job) now."""
        self._wake.set()

    def stop(self, timeout_s: float | None = None) -> None:
        """Stop the loop; a running subprocess is terminated (`cancel_grace_s`, then killed)."""
        self._stopping.set()
        self._wake.set()  # the loop terminates the subprocess itself (see `_run`)
        if self._thread is not None:
            self._thread.join(self.cancel_grace_s + 5.0 if timeout_s is None else timeout_s)

    def _loop(self) -> None:
        last_recover = -float("inf")
        while not self._stopping.is_set():
            try:
                if time.monotonic() - last_recover >= self.table.stale_after_s / 2:
                    self.table.recover(on_cancelled=self._stop_leftover)
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
        cmd = self.command(job.spec, run_dir)
        log.info("job %s: attempt %d: %s", job.id, job.attempts, " ".join(cmd))
        with (run_dir / LOG_NAME).open("ab") as out:
            out.write(f"--- attempt {job.attempts}: {' '.join(cmd)}\n".encode())
            out.flush()
            try:
                stopped = stop_leftover(run_dir, self.cancel_grace_s)
            except TimeoutError as err:  # it would not let go: try again later (max_attempts)
                out.write(f"--- not started: {err}\n".encode())
                self.table.release(job.id, job.attempts)
                return
            if stopped is not None:
                out.write(f"--- {stopped}\n".encode())
                out.flush()
            proc = subprocess.Popen(
                leashed(cmd, run_dir),
                stdout=out,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                env={**os.environ, **self._store_env},
                cwd=_PROJECT_ROOT,
                start_new_session=True,
            )
            if not self._watch(job, proc, out):
                return
        self.table.finish(job.id, proc.returncode, read_log(run_dir, 8_000), job.attempts)
        log.info("job %s: exit code %d", job.id, proc.returncode)

    def _watch(self, job: Job, proc: subprocess.Popen[bytes], out: BinaryIO) -> bool:
        """Poll until the trainer exits (True) or is stopped here: cancelled, this runner
        stopping, or its lease lost (False; the row is then recorded, released or not ours)."""
        last_beat = renewed = time.monotonic()
        while proc.poll() is None:
            self._wake.wait(self.poll_s)
            self._wake.clear()
            if self._check_status(job.id) is JobStatus.cancelling:
                self._cancel(job, proc, out)
                return False
            if self._stopping.is_set():
                terminate(proc, self.cancel_grace_s)
                self.table.release(job.id, job.attempts)  # the next process resumes it
                log.info("job %s: left for the next process", job.id)
                return False
            if time.monotonic() - last_beat < self.heartbeat_s:
                continue
            last_beat = time.monotonic()
            held = self._renew(job)
            if held:
                renewed = last_beat
            elif held is None and last_beat - renewed < self.table.stale_after_s - self.heartbeat_s:
                continue  # the database is away: the lease still runs
            elif held is None or self._check_status(job.id) is not JobStatus.cancelling:
                why = "it was taken over" if held is False else "the database stayed away"
                out.write(f"--- lease lost ({why}): stopping process group {proc.pid}\n".encode())
                out.flush()
                how = terminate(proc, self.cancel_grace_s)
                log.warning(
                    "job %s: attempt %d lost its lease (%s): %s", job.id, job.attempts, why, how
                )
                return False
        return True

    def _renew(self, job: Job) -> bool | None:
        """Renew the job's lease: whether it is still this attempt's, None if the database
        could not be asked."""
        try:
            return self.table.heartbeat(job.id, job.attempts)
        except Exception:
            log.exception("job %s: could not renew its lease", job.id)
            return None

    def _stop_leftover(self, run_dir: str) -> None:
        """A job recovered as cancelled: stop a trainer still working in its directory."""
        try:
            stopped = stop_leftover(run_dir, self.cancel_grace_s)
        except (TimeoutError, OSError):
            log.exception("could not stop the trainer left in %s", run_dir)
            return
        if stopped is not None:
            append_log(run_dir, f"--- {stopped}")

    def _check_status(self, job_id: str) -> JobStatus:
        try:
            return self.table.status(job_id)
        except Exception:  # the database is briefly away: keep training, ask again next poll
            log.exception("job %s: could not read its status", job_id)
            return JobStatus.running

    def _cancel(self, job: Job, proc: subprocess.Popen[bytes], out: BinaryIO) -> None:
        """Stop a job somebody cancelled; its log and row both say how it ended."""
        out.write(f"--- cancelled: stopping process group {proc.pid} (SIGTERM)\n".encode())
        out.flush()
        started = time.monotonic()
        how = terminate(proc, self.cancel_grace_s)
        elapsed = time.monotonic() - started
        out.write(
            f"--- cancelled: {how} after {elapsed:.1f} s, exit code {proc.returncode}\n".encode()
        )
        out.flush()
        tail = read_log(job.run_dir, 8_000)
        self.table.finish_cancelled(job.id, proc.returncode, tail, job.attempts)
        log.info("job %s: cancelled (%s, exit code %d)", job.id, how, proc.returncode)


def terminate(proc: subprocess.Popen[bytes], grace_s: float) -> str:
    """SIGTERM to the process group, SIGKILL if it is still there after `grace_s`; says which
    ended it. Either signal is safe for the store: `coexist train` registers each version in one
    transaction, so a version is there whole or not at all."""
    _signal_group(proc, signal.SIGTERM)
    try:
        proc.wait(grace_s)
        return "ended on SIGTERM"
    except subprocess.TimeoutExpired:
        _signal_group(proc, signal.SIGKILL)
        proc.wait()
        return f"killed (SIGKILL) after ignoring SIGTERM for {grace_s:g} s"


def _signal_group(proc: subprocess.Popen[bytes], sig: signal.Signals) -> None:
    with contextlib.suppress(ProcessLookupError):  # already gone
        os.killpg(proc.pid, sig)  # its own session: the group id is its pid
