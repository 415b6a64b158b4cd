"""The images are reproducible: docker/Dockerfile's base images and the third-party images of
docker/compose.yaml are pinned by digest, every dependency comes from docker/requirements.lock (pinned, covering pyproject's requirements, and
current with the installed versions), and the dependency layer is built before any code is
copied, so a code change does not reinstall the dependencies."""

from __future__ import annotations

import importlib.util
import re
import tomllib
from pathlib import Path

import yaml
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

REPO = Path(__file__).resolve().parents[2]
DOCKERFILE = REPO / "docker" / "Dockerfile"
LOCK = REPO / "docker" / "requirements.lock"
COMPOSE = REPO / "docker" / "compose.yaml"
DIGEST = re.compile(r"^[\w./-]+:[\w.-]+@sha256:[0-9a-f]{64}$")
NOT_LOCKED = {"coexist", "coexist-client", "torch"}  # the code layer, and torch's own index


def _instructions() -> list[tuple[str, str]]:
    joined = DOCKERFILE.read_text().replace("\\\n", " ")
    lines = [line.strip() for line in joined.splitlines()]
    return [
        (line.split(" ", 1)[0].upper(), line.split(" ", 1)[1])
        for line in lines
        if line and not line.startswith("#")
    ]


def _lock() -> dict[str, str]:
    pins: dict[str, str] = {}
    for line in LOCK.read_text().splitlines():
        if line and not line.startswith("#"):
            name, sep, version = line.partition("==")
            assert sep and version, f"not pinned: {line}"
            pins[canonicalize_name(name)] = version
    return pins


def test_every_base_image_is_pinned_by_digest() -> None:
    stages: set[str] = set()
    bases = []
    for instruction, rest in _instructions():
        if instruction == "FROM":
            base, _, name = rest.partition(" AS ")
            if base.strip() not in stages:
                bases.append(base.strip())
            stages.add(name.strip())
    assert bases, "no FROM found"
    for base in bases:
        assert DIGEST.match(base), f"not pinned by digest: {base}"


def test_every_compose_image_not_built_here_is_pinned_by_digest() -> None:
    services = yaml.safe_load(COMPOSE.read_text())["services"]
    third_party = {name: s["image"] for name, s in services.items() if "build" not in s}
    assert {"postgres", "lb", "prometheus", "grafana"} <= set(third_party), third_party
    for name, image in third_party.items():
        assert DIGEST.match(image), f"{name}: not pinned by digest: {image}"
        tag = image.split("@")[0].rsplit(":", 1)[1]
        assert "latest" not in tag, f"{name}: a moving tag beside the digest: {image}"
    built = [s["image"] for s in services.values() if "build" in s]
    assert built and all(image.startswith("coexist-") for image in built), built


def test_the_lock_pins_every_requirement_of_the_images() -> None:
    pins = _lock()
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    sdk = tomllib.loads((REPO / "sdk" / "pyproject.toml").read_text())["project"]
    wanted = [*project["dependencies"], *sdk["dependencies"]]
    for extra in ("train", "postgres", "redis"):
        wanted += project["optional-dependencies"][extra]
    for line in wanted:
        req = Requirement(line)
        name = canonicalize_name(req.name)
        if name in NOT_LOCKED:
            continue
        assert name in pins, f"{req.name} is not in docker/requirements.lock"
        assert req.specifier.contains(Version(pins[name]), prereleases=True), (line, pins[name])


def test_the_lock_is_current_with_the_installed_versions() -> None:
    spec = importlib.util.spec_from_file_location("lock", REPO / "scripts" / "lock_image_deps.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert LOCK.read_text() == module.render(), "run: python scripts/lock_image_deps.py"


def test_dependencies_and_code_are_separate_layers() -> None:
    steps = _instructions()
    lock_install = next(
        k
        for k, (i, rest) in enumerate(steps)
        if i == "RUN" and "-r docker/requirements.lock" in rest
    )
    assert "--no-deps" in steps[lock_install][1]  # the lock is the whole closure
    code = [
        k
        for k, (i, rest) in enumerate(steps)
        if i == "COPY" and rest.split()[0] in ("sdk", "services", "envs")
    ]
    assert code and lock_install < min(code), "code is copied before the dependencies install"
    copied_before = [rest for i, rest in steps[:lock_install] if i == "COPY"]
    assert copied_before == ["docker/requirements.lock ./docker/requirements.lock"]
    installs = [
        rest for i, rest in steps[lock_install + 1 :] if i == "RUN" and "pip install" in rest
    ]
    assert all("--no-deps" in rest for rest in installs), installs  # nothing resolved anew
