"""What a Docker engine would read from docker/, read without one (imported by test_compose.py).

| helper             | what                                                                   |
|--------------------|------------------------------------------------------------------------|
| `dockerfile_stages`| the stages of docker/Dockerfile with what each inherits: ENTRYPOINT,   |
|                    | CMD, HEALTHCHECK, USER, ENV, ARG defaults, COPY sources                |
| `interpolate`      | compose's `${VAR}`, `${VAR:-default}`, `${VAR:?error}`                  |
| `service_argv`     | a compose service's full argv: its (or its image's) ENTRYPOINT + CMD   |
| `parse_coexist`    | parses an argv with the CLI's click commands, as `coexist` would       |
| `RoundRobinProxy`  | a TCP round-robin load balancer in a thread: the `lb` stand-in         |
"""

from __future__ import annotations

import asyncio
import json
import re
import shlex
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import typer

REPO = Path(__file__).resolve().parents[2]
DOCKER = REPO / "docker"


@dataclass
class Stage:
    name: str
    base: str
    entrypoint: list[str] | None = None
    cmd: list[str] | None = None
    healthcheck: list[str] | None = None  # exec form argv, or ["NONE"]
    user: str | None = None
    env: dict[str, str] = field(default_factory=dict)
    args: dict[str, str] = field(default_factory=dict)
    copies: list[str] = field(default_factory=list)


def _logical_lines(text: str) -> list[str]:
    lines, current = [], ""
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.endswith("\\"):
            current += line[:-1] + " "
            continue
        lines.append(current + line)
        current = ""
    return lines


def _exec_form(text: str) -> list[str]:
    value = json.loads(text)
    assert isinstance(value, list), f"expected the exec (JSON array) form: {text}"
    return [str(v) for v in value]


def dockerfile_stages(path: Path = DOCKER / "Dockerfile") -> dict[str, Stage]:
    stages: dict[str, Stage] = {}
    global_args: dict[str, str] = {}
    stage: Stage | None = None
    for line in _logical_lines(path.read_text()):
        instruction, _, rest = line.partition(" ")
        instruction = instruction.upper()
        if instruction == "FROM":
            base, _, name = rest.partition(" AS ")
            parent = stages.get(base.strip())
            stage = Stage(name.strip(), base.strip())
            if parent is not None:  # a stage built on another inherits its settings
                stage.entrypoint, stage.cmd = parent.entrypoint, parent.cmd
                stage.healthcheck, stage.user = parent.healthcheck, parent.user
                stage.env = dict(parent.env)
            stages[stage.name] = stage
        elif instruction == "ARG":
            key, _, default = rest.partition("=")
            (stage.args if stage else global_args)[key.strip()] = default.strip().strip('"')
        elif stage is None:
            continue
        elif instruction == "ENTRYPOINT":
            stage.entrypoint = _exec_form(rest)
        elif instruction == "CMD":
            stage.cmd = _exec_form(rest)
        elif instruction == "USER":
            stage.user = rest.strip()
        elif instruction == "HEALTHCHECK":
            _, _, exec_part = rest.partition("CMD ")
            stage.healthcheck = ["NONE"] if rest.strip() == "NONE" else _exec_form(exec_part)
        elif instruction == "ENV":
            for item in shlex.split(rest):
                key, _, value = item.partition("=")
                stage.env[key] = value
        elif instruction == "COPY" and not rest.startswith("--from"):
            stage.copies += shlex.split(rest)[:-1]
    return stages


_VAR = re.compile(r"\$\{(?P<name>\w+)(?:(?P<op>:-|:\?)(?P<arg>[^}]*))?\}")


def interpolate(value: Any, env: Mapping[str, str]) -> Any:
    """Compose's variable substitution on strings, lists and mappings."""
    if isinstance(value, dict):
        return {k: interpolate(v, env) for k, v in value.items()}
    if isinstance(value, list):
        return [interpolate(v, env) for v in value]
    if not isinstance(value, str):
        return value

    def substitute(match: re.Match[str]) -> str:
        name, op, arg = match["name"], match["op"], match["arg"]
        if env.get(name):
            return env[name]
        if op == ":?":
            raise KeyError(f"{name}: {arg}")
        return arg if op == ":-" else ""

    return _VAR.sub(substitute, value)


def service_argv(service: Mapping[str, Any], stages: Mapping[str, Stage]) -> list[str]:
    """What the container runs: ENTRYPOINT + CMD, each from compose or else from the image."""
    stage = stages[service["build"]["target"]]
    entrypoint = service.get("entrypoint", stage.entrypoint) or []
    command = service.get("command", stage.cmd) or []
    return [*entrypoint, *command]


def parse_coexist(argv: Sequence[str]) -> Any:
    """Parse `coexist ...` with the CLI's own click commands (options, types, choices): an
    unknown sub-command or option raises a click error, as running it would. Returns the leaf
    command's context (typer vendors its own click, so groups are told by their `commands`)."""
    from cli.main import app

    assert argv[0] == "coexist", argv
    command: Any = typer.main.get_command(app)
    path, args = ["coexist"], list(argv[1:])
    while hasattr(command, "commands"):
        name = args.pop(0)
        assert name in command.commands, f"`{' '.join(path)}` has no sub-command {name!r}"
        command = command.commands[name]
        path.append(name)
    return command.make_context(" ".join(path), args)


class RoundRobinProxy:
    """Each new TCP connection goes to the next backend (HTTP/1.1 and gRPC alike); `counts`
    says how many each backend got. A stand-in for Envoy without its health checks."""

    def __init__(self, backends: Sequence[tuple[str, int]]) -> None:
        self.backends = list(backends)
        self.counts = [0] * len(self.backends)
        self.port = 0
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)
        self._server: asyncio.Server | None = None

    def __enter__(self) -> RoundRobinProxy:
        self._thread.start()
        future = asyncio.run_coroutine_threadsafe(self._start(), self._loop)
        self.port = future.result(timeout=10)
        return self

    def __exit__(self, *exc: object) -> None:
        asyncio.run_coroutine_threadsafe(self._stop(), self._loop).result(timeout=10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=10)
        self._loop.close()

    async def _stop(self) -> None:
        if self._server is not None:
            self._server.close()
        pending = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        for task in pending:
            task.cancel()
        await asyncio.gather(*pending, return_exceptions=True)

    async def _start(self) -> int:
        self._server = await asyncio.start_server(self._handle, "127.0.0.1", 0)
        return int(self._server.sockets[0].getsockname()[1])

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        k = sum(self.counts) % len(self.backends)
        self.counts[k] += 1
        try:
            up_reader, up_writer = await asyncio.open_connection(*self.backends[k])
        except OSError:
            writer.close()
            return
        await asyncio.gather(_pipe(reader, up_writer), _pipe(up_reader, writer))


async def _pipe(source: asyncio.StreamReader, sink: asyncio.StreamWriter) -> None:
    try:
        while data := await source.read(65536):
            sink.write(data)
            await sink.drain()
    except ConnectionError:
        pass
    finally:
        sink.close()
