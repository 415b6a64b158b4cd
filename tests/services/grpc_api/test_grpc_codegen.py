"""The committed generated code (the server's and the SDK's copies) equals what
`scripts/gen_proto.sh` produces from proto/ now."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
COMMITTED = ROOT / "services" / "grpc_api" / "gen"
COMMITTED_SDK = ROOT / "sdk" / "coexist_client" / "gen"


def _files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and "__pycache__" not in p.parts
    }


def test_generated_code_has_not_drifted(tmp_path: Path) -> None:
    out, sdk_out = tmp_path / "gen", tmp_path / "sdk_gen"
    subprocess.run(
        ["bash", str(ROOT / "scripts" / "gen_proto.sh"), str(out), str(sdk_out)],
        check=True,
        env={"PYTHON": sys.executable, "PATH": "/usr/bin:/bin"},
        capture_output=True,
    )
    fresh, committed = _files(out), _files(COMMITTED)
    assert sorted(fresh) == sorted(committed), "files differ: run scripts/gen_proto.sh"
    stale = [name for name in fresh if fresh[name] != committed[name]]
    assert not stale, f"stale generated files {stale}: run scripts/gen_proto.sh"
    assert (
        b"from services.grpc_api.gen.coexist.v1 import policy_pb2"
        in fresh["coexist/v1/policy_pb2_grpc.py"]
    )
    sdk_fresh, sdk_committed = _files(sdk_out), _files(COMMITTED_SDK)
    assert sorted(sdk_fresh) == sorted(sdk_committed), "SDK files differ: run scripts/gen_proto.sh"
    stale = [name for name in sdk_fresh if sdk_fresh[name] != sdk_committed[name]]
    assert not stale, f"stale SDK generated files {stale}: run scripts/gen_proto.sh"
    assert (
        b"from coexist_client.gen.coexist.v1 import policy_pb2"
        in sdk_fresh["coexist/v1/policy_pb2_grpc.py"]
    )
