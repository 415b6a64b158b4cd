"""Network counts, the timing log and its attribution to the networks each command trained."""

from __future__ import annotations

import json
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from evaluation.paper.scaling import networks_needed, training_costs
from evaluation.timing import LoggedCommand, append_entry, attribute_wall_times, main, read_log
from model_store.entities import Lineage, ModelVersion

T0 = datetime(2026, 1, 1, 12, 0, 0, tzinfo=UTC)


def version(name: str, at_s: float, **config: object) -> ModelVersion:
    return ModelVersion(
        name=name,
        version=1,
        spec={},
        sha256="0" * 64,
        size_bytes=1,
        created_at=(T0 + timedelta(seconds=at_s)).replace(tzinfo=None),  # stores give naive UTC
        status="ready",
        lineage=Lineage(config=dict(config)),
    )


def test_networks_needed_match_the_paper() -> None:
    assert networks_needed(35, 2) == {"sl": 35, "nail": 70, "aail": 70, "jl": 1225}
    assert networks_needed(35, 5)["jl"] == 52_521_875  # the paper's number
    assert networks_needed(35, 1)["aail"] == 35  # alone, there is nothing to have impact on
    with pytest.raises(ValueError, match="n_goals"):
        networks_needed(0, 2)


def test_wall_time_is_split_at_the_last_registration_of_each_kind() -> None:
    # one command trains 2 tasks (registered at 100 s), then 2 impacts (at 160 s), ends at 170 s
    command = LoggedCommand("coexist train zoo", T0, T0 + timedelta(seconds=170), 170.0)
    versions = [
        ("task", version("t/a", 99.0)),
        ("task", version("t/b", 100.0)),
        ("impact", version("i/a", 159.0)),
        ("impact", version("i/b", 160.0)),
        ("joint", version("j/ab", 500.0)),  # registered by another command: not attributed
    ]
    costs = attribute_wall_times([command], versions)
    assert set(costs) == {"task", "impact"}
    assert costs["task"].wall_s == pytest.approx(100.0) and costs["task"].networks == 2
    assert costs["impact"].wall_s == pytest.approx(60.0)
    assert costs["impact"].per_network_s == pytest.approx(30.0)


def test_training_costs_from_lineage() -> None:
    config = {"total_steps": 100, "envs_per_net": 4, "warmup_steps": 10, "hidden": [8, 8]}
    versions = [("task", version("t/a", 1, **config)), ("joint", version("j", 2, **config))]
    rows = {r.kind: r for r in training_costs(versions, [])}
    assert set(rows) == {"task", "joint"}
    assert rows["task"].transitions == 400 and rows["task"].updates == 90
    assert rows["task"].hidden == "8-8" and rows["task"].wall is None


def test_timing_log_round_trip_and_wrapper(tmp_path: Path) -> None:
    log = tmp_path / "log.jsonl"
    append_entry(log, "x", T0, T0 + timedelta(seconds=2.5), 0)
    append_entry(log, "failed", T0, T0, 1)  # failed commands are ignored
    [entry] = read_log(log)
    assert entry.wall_s == 2.5 and entry.started_at == T0
    assert main(["--log", str(log), "--", sys.executable, "-c", "pass"]) == 0
    last = json.loads(log.read_text().splitlines()[-1])
    assert last["returncode"] == 0 and last["command"].endswith("-c pass")
    assert read_log(tmp_path / "missing.jsonl") == []
    (tmp_path / "bad.jsonl").write_text("{not json\n")
    with pytest.raises(ValueError, match=r"bad\.jsonl:1"):
        read_log(tmp_path / "bad.jsonl")
