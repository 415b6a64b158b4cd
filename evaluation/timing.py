"""Measured training cost: a wall-clock log of training commands, attributed to the networks
each command registered.

    python -m evaluation.timing --log reports/paper/training_log.jsonl -- \
        coexist train joint --combos c+c4,a2+b3 --store-url ...

runs the command and appends one JSON line `{"command", "started_at", "finished_at", "wall_s",
"returncode"}` (UTC ISO times). `attribute_wall_times` splits each logged command's time among
the model kinds it registered: the versions created between its start and end, ordered by
creation time; the segment of a kind runs from the previous boundary (the start, or the last
registration of the kind trained before it) to its own last registration. A command that trains
tasks then impacts (`coexist train zoo`) is thus split at the last task registration.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from model_store.entities import ModelVersion


@dataclass(frozen=True)
class LoggedCommand:
    command: str
    started_at: datetime
    finished_at: datetime
    wall_s: float


@dataclass(frozen=True)
class KindCost:
    kind: str
    networks: int
    wall_s: float

    @property
    def per_network_s(self) -> float:
        return self.wall_s / self.networks if self.networks else float("nan")


def _utc(moment: datetime) -> datetime:
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)


def append_entry(log: Path, command: str, started: datetime, finished: datetime, rc: int) -> None:
    entry = {
        "command": command,
        "started_at": _utc(started).isoformat(),
        "finished_at": _utc(finished).isoformat(),
        "wall_s": round((finished - started).total_seconds(), 3),
        "returncode": rc,
    }
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("a") as handle:
        handle.write(json.dumps(entry) + "\n")


def read_log(log: Path) -> list[LoggedCommand]:
    """The successful commands of a timing log (a missing file is an empty log)."""
    if not log.exists():
        return []
    entries = []
    for number, line in enumerate(log.read_text().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            data = json.loads(line)
            if data.get("returncode", 0) != 0:
                continue
            entries.append(
                LoggedCommand(
                    str(data["command"]),
                    _utc(datetime.fromisoformat(data["started_at"])),
                    _utc(datetime.fromisoformat(data["finished_at"])),
                    float(data["wall_s"]),
                )
            )
        except (ValueError, KeyError, TypeError) as err:
            raise ValueError(f"{log}:{number}: not a timing entry ({err})") from None
    return entries


def attribute_wall_times(
    commands: Iterable[LoggedCommand], versions: Sequence[tuple[str, ModelVersion]]
) -> dict[str, KindCost]:
    """Wall time and network count per kind (module docstring); `versions` are (kind, version)."""
    totals: dict[str, list[float]] = {}
    for command in commands:
        inside = sorted(
            (
                (_utc(v.created_at), kind)
                for kind, v in versions
                if command.started_at <= _utc(v.created_at) <= command.finished_at
            ),
        )
        last_of: dict[str, datetime] = {}
        count_of: dict[str, int] = {}
        for moment, kind in inside:
            last_of[kind] = moment
            count_of[kind] = count_of.get(kind, 0) + 1
        boundary = command.started_at
        for kind, last in sorted(last_of.items(), key=lambda item: item[1]):
            entry = totals.setdefault(kind, [0.0, 0.0])
            entry[0] += count_of[kind]
            entry[1] += (last - boundary).total_seconds()
            boundary = last
    return {k: KindCost(k, int(n), wall) for k, (n, wall) in totals.items()}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Run a training command and log its wall time.")
    parser.add_argument("--log", type=Path, required=True, help="JSON-lines file to append to.")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- then the command")
    args = parser.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("expected a command after --")
    started = datetime.now(UTC)
    rc = subprocess.call(command)
    append_entry(args.log, " ".join(command), started, datetime.now(UTC), rc)
    return rc


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
