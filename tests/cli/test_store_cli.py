"""`coexist models ...` through typer's CliRunner: list, show, promote, archive, export/import."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from cli.models import app
from model_store.sql import SqlModelStore
from model_store.testing import qnet_spec, qnet_weights, test_lineage

NAME = "particle/task/a3"
SPEC = qnet_spec(obs_dim=8, n_actions=5, hidden=(16,))
runner = CliRunner()


@pytest.fixture
def url(tmp_path: Path) -> str:
    url = f"sqlite:///{tmp_path / 'models.db'}"
    with SqlModelStore(url) as store:
        store.create_model(
            NAME,
            env="particle",
            kind="task",
            goals=["a3"],
            obs_dim=8,
            n_actions=5,
            tags={"gate": "passed"},
            description="reach a3",
        )
        store.create_model(
            "particle/impact/b1",
            env="particle",
            kind="impact",
            goals=["b1"],
            obs_dim=8,
            n_actions=5,
        )
        for seed in (1, 2):
            store.register_version(
                NAME,
                spec=SPEC,
                weights=qnet_weights(SPEC, seed=seed),
                lineage=test_lineage(seed=seed),
            )
    return url


def _run(*args: str, code: int = 0):
    result = runner.invoke(app, [*args], env={"COLUMNS": "200"})
    assert result.exit_code == code, result.output
    return result


def test_list_and_filters(url: str) -> None:
    output = _run("list", "--store-url", url).output
    assert "2 model(s)" in output and NAME in output and "particle/impact/b1" in output
    assert "latest→2" in output and "gate=passed" in output
    only_tasks = _run("list", "--kind", "task", "--store-url", url).output
    assert "1 model(s)" in only_tasks and "particle/impact/b1" not in only_tasks


def test_show_lists_versions_aliases_and_lineage(url: str) -> None:
    output = _run("show", NAME, "--version", "1", "--store-url", url).output
    assert "reach a3" in output and '"latest": 2' in output
    sha1 = hashlib.sha256(qnet_weights(SPEC, seed=1)).hexdigest()
    assert sha1[:12] in output and "seed 2, code test, by pytest" in output
    assert '"final_return": 12.5' in output  # --version prints the full lineage


def test_promote_archive_and_clear_errors(url: str) -> None:
    assert "moved to version 1" in _run("promote", NAME, "1", "--store-url", url).output
    moved = _run("promote", NAME, "2", "--store-url", url).output
    assert "moved from 1 to version 2" in moved
    assert "archived" in _run("archive", NAME, "1", "--store-url", url).output
    refused = _run("archive", NAME, "2", "--store-url", url, code=1)
    assert "production" in refused.output and "Traceback" not in refused.output
    unknown = _run("show", "particle/task/zz", "--store-url", url, code=1)
    assert "not found" in unknown.output
    bad = _run("promote", NAME, "1", "--alias", "Bad Alias", "--store-url", url, code=2)
    assert "alias" in bad.output
    with SqlModelStore(url) as store:
        assert store.get_model(NAME).aliases == {"latest": 2, "production": 2}
        assert store.get_version(NAME, 1).status == "archived"


def test_export_import_round_trip(url: str, tmp_path: Path) -> None:
    out = tmp_path / "export"
    _run("export", f"{NAME}@latest", "--out", str(out), "--store-url", url)
    blob = qnet_weights(SPEC, seed=2)
    assert (out / "weights.safetensors").read_bytes() == blob
    assert (
        out / "sha256"
    ).read_text() == f"{hashlib.sha256(blob).hexdigest()}  weights.safetensors\n"
    assert json.loads((out / "spec.json").read_text()) == SPEC
    assert json.loads((out / "lineage.json").read_text())["seed"] == 2

    other = f"sqlite:///{tmp_path / 'other.db'}"
    _run("import", str(out), "--alias", "production", "--store-url", other)
    with SqlModelStore(other) as store:
        mv = store.resolve(NAME)
        assert mv.version == 1 and store.load_weights(NAME, 1) == blob
        assert mv.lineage.seed == 2 and store.get_model(NAME).tags == {"gate": "passed"}
    again = _run("import", str(out), "--store-url", url).output
    assert f"{NAME}/3" in again

    (out / "weights.safetensors").write_bytes(blob[: len(blob) // 2])
    tampered = _run("import", str(out), "--store-url", url, code=1)
    assert "sha256 does not match" in tampered.output
    (out / "sha256").unlink()
    truncated = _run("import", str(out), "--store-url", url, code=2)  # caught by validation
    assert "weights" in truncated.output and "safetensors" in truncated.output
    missing = _run("import", str(tmp_path / "nowhere"), "--store-url", url, code=2)
    assert "spec.json" in missing.output


def test_a_mistyped_store_path_is_an_error_naming_it(tmp_path: Path) -> None:
    typo = tmp_path / "modles.db"
    result = runner.invoke(app, ["list", "--store-url", f"sqlite:///{typo}"])
    assert result.exit_code == 2, result.output
    assert f"no SQLite database at '{typo}'" in " ".join(result.output.split())
    assert "model(s)" not in result.output and not typo.exists()


def test_serve_refuses_a_mistyped_store_path_unless_asked_to_create_it(tmp_path: Path) -> None:
    typo = tmp_path / "modles.db"
    env = {k: v for k, v in os.environ.items() if not k.startswith("COEXIST_")}
    served = subprocess.run(
        [sys.executable, "-m", "cli.main", "serve", "--store-url", f"sqlite:///{typo}"],
        env={**env, "COEXIST_DEV_MODE": "1", "COEXIST_DATA_DIR": str(tmp_path / "data")},
        cwd=Path(__file__).resolve().parents[2],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert served.returncode == 2, served.stderr
    assert f"no SQLite database at '{typo}'" in served.stderr
    assert "--create-store" in served.stderr and not typo.exists()
