"""One trainer per job, whatever dies: how the job runner starts a trainer, and how it finds one
that an earlier attempt left behind.

    python trainer/jobs/leash.py RUN_DIR PARENT_PID -- COMMAND ...

The runner starts every trainer through this file (`leashed`; run as a script, it imports only
the standard library, so it costs the trainer's start a few milliseconds), which, in the new
process:

1. asks the kernel for a parent-death signal (Linux `prctl(PR_SET_PDEATHSIG, SIGKILL)`): when the
   thread that started it, the server's job-runner thread, ends (a `kill -9` of the server
   included), the trainer is killed too. SIGKILL, because a trainer may ignore SIGTERM and the
   store is safe either way (each version registers in one transaction). If the parent is gone
   already, it exits at once (checked after asking, so there is no window);
2. takes the run directory's lock, `RUN_DIR/trainer.lock` (an exclusive `flock`), writes its pid
   into it and keeps the descriptor open across the exec: the lock is held exactly as long as the
   trainer (or a process it started with the descriptor) lives. It exits with `LOCKED` if another
   process holds it;
3. execs COMMAND: the trainer replaces this process (same pid, its own process group).

Before an attempt the runner calls `stop_leftover(run_dir)`: a lock still held means a trainer of
an earlier attempt works there (its server died on a system without the parent-death signal, or
it was started some other way); its process group gets SIGTERM, then SIGKILL after the grace
period, and the new attempt starts only once the lock is free. The pid in the lock file is
trusted only if that process holds the lock file open (`/proc/PID/fd`, where there is a /proc).
"""

from __future__ import annotations

import contextlib
import ctypes
import fcntl
import os
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path

LOCK_NAME = "trainer.lock"
LOCKED = 75  # EX_TEMPFAIL: the run directory is another trainer's
_PR_SET_PDEATHSIG = 1


def leashed(command: Sequence[str], run_dir: str | Path) -> list[str]:
    """`command` started through this module by the current process (module docstring)."""
    return [sys.executable, __file__, str(run_dir), str(os.getpid()), "--", *command]


def lock_holder(run_dir: str | Path) -> int | None:
    """The pid of the process holding `run_dir`'s lock, None when it is free (0: held, but by
    no process this machine can name)."""
    path = Path(run_dir) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            text = os.pread(fd, 32, 0).decode("ascii", errors="replace").strip()
            pid = int(text) if text.isdigit() else 0
            return pid if pid and _holds(pid, fd) else 0
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def _holds(pid: int, fd: int) -> bool:
    """Whether process `pid` has the file of descriptor `fd` open (True without a /proc)."""
    proc = Path(f"/proc/{pid}/fd")
    if not Path("/proc/self/fd").is_dir():
        return True
    target = os.fstat(fd)
    with contextlib.suppress(OSError):  # gone, or not ours to inspect
        for entry in proc.iterdir():
            with contextlib.suppress(OSError):
                st = os.stat(entry)
                if (st.st_dev, st.st_ino) == (target.st_dev, target.st_ino):
                    return True
    return False


def stop_leftover(run_dir: str | Path, grace_s: float, wait_s: float = 10.0) -> str | None:
    """Stop a trainer that holds `run_dir` (module docstring); what was done, for the job's log,
    or None when the directory was free. Raises `TimeoutError` if it stays held."""
    pid = lock_holder(run_dir)
    if pid is None:
        return None
    how = f"a trainer of an earlier attempt (pid {pid or 'unknown'}) still held the run directory"
    if pid:
        _signal_group(pid, signal.SIGTERM)
        if _wait_free(run_dir, grace_s):
            return f"{how}: stopped it (SIGTERM)"
        _signal_group(pid, signal.SIGKILL)
    if _wait_free(run_dir, wait_s):
        return f"{how}: stopped it (SIGKILL)" if pid else f"{how}: it let go"
    raise TimeoutError(f"{how} and did not let go within {grace_s + wait_s:g} s")


def _signal_group(pid: int, sig: signal.Signals) -> None:
    """Signal the process group `pid` leads (a runner's trainer does), else the process."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        if os.getpgid(pid) == pid:
            os.killpg(pid, sig)
        else:
            os.kill(pid, sig)


def _wait_free(run_dir: str | Path, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while lock_holder(run_dir) is not None:
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def _die_with_parent(parent: int) -> None:
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    if os.getppid() != parent:  # it died before the signal was armed
        sys.exit(f"leash: the job runner (pid {parent}) is gone; not starting the trainer")


def main(argv: Sequence[str]) -> int:
    if len(argv) < 4 or argv[2] != "--" or not argv[1].isdigit():
        sys.exit("usage: python leash.py RUN_DIR PARENT_PID -- COMMAND ...")
    run_dir, parent, command = Path(argv[0]), int(argv[1]), list(argv[3:])
    _die_with_parent(parent)
    run_dir.mkdir(parents=True, exist_ok=True)
    fd = os.open(run_dir / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        print(f"leash: {run_dir} is held by pid {lock_holder(run_dir)}", file=sys.stderr)
        return LOCKED
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    os.set_inheritable(fd, True)  # the trainer keeps the lock
    sys.stdout.flush()
    os.execvp(command[0], command)
    raise AssertionError("unreachable: exec returned")  # pragma: no cover


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
