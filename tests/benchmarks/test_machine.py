"""benchmarks/machine.py: the one-line description of the machine every benchmark prints."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import machine  # noqa: E402

CPUINFO = """processor\t: 0
vendor_id\t: GenuineIntel
cpu family\t: 6
model\t\t: 207
model name\t: Intel(R) Xeon(R) Processor
flags\t\t: fpu sse2 avx avx2 fma avx512f avx512bw

processor\t: 1
model name\t: another processor, not read
"""


def test_the_line_names_the_model_the_cpus_the_vectors_and_the_caches() -> None:
    line = machine.describe_from(CPUINFO, 2, {1: "48K", 2: "2048K", 3: "266240K"})
    assert line == (
        "Intel(R) Xeon(R) Processor (family 6, model 207), 2 CPUs, AVX-512, "
        "L2 2 MiB per core, L3 260 MiB"
    )


def test_what_is_missing_is_left_out() -> None:
    avx2_only = CPUINFO.replace(" avx512f avx512bw", "").replace("cpu family\t: 6\n", "")
    assert machine.describe_from(avx2_only, 1, {2: "512K"}) == (
        "Intel(R) Xeon(R) Processor, 1 CPU, AVX2, L2 512 KiB per core"
    )
    assert machine.describe_from("", 4, {}).endswith(", 4 CPUs")  # no /proc/cpuinfo


def test_the_last_level_cache_is_read_in_bytes() -> None:
    assert machine.last_level_cache_bytes({1: "48K", 2: "2048K", 3: "266240K"}) == 260 * 2**20
    assert machine.last_level_cache_bytes({2: "512K"}) == 512 * 1024  # no L3: the L2
    assert machine.last_level_cache_bytes({3: "32M"}) == 32 * 2**20
    assert machine.last_level_cache_bytes({3: "a lot"}) is None
    assert machine.last_level_cache_bytes({}) is None


def test_this_machine_is_described() -> None:
    line = machine.describe()
    assert line and "CPU" in line
