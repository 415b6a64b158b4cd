"""The machine a benchmark ran on, in one line for its header and its JSON.

Why every benchmark prints it: the same tree meets a ratio on one kind of machine and misses it
on another (docs/performance.md measures three kinds: their vector units, L2 sizes and the
L3's pace move the verdicts), so a figure without its machine cannot be compared with anything.

    describe()  # the form, on a KVM guest: "Intel(R) Xeon(R) Processor (family 6, model
                # 207), 2 CPUs, AVX-512, L2 2 MiB per core, L3 260 MiB"

Read from Linux's `/proc/cpuinfo` and `/sys/devices/system/cpu/cpu0/cache`; where those are
missing (another OS) the line says what `platform` knows.
"""

from __future__ import annotations

import os
import platform
from pathlib import Path

CACHE = Path("/sys/devices/system/cpu/cpu0/cache")


def describe() -> str:
    """This machine in one line (module docstring)."""
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text()
    except OSError:
        cpuinfo = ""
    return describe_from(cpuinfo, os.cpu_count() or 1, _cache_sizes())


def describe_from(cpuinfo: str, cpus: int, caches: dict[int, str]) -> str:
    """The line of `describe` from the text of `/proc/cpuinfo` (its first processor), the
    number of CPUs and the cache sizes by level (as sysfs writes them: "2048K")."""
    first = _first_processor(cpuinfo)
    model = first.get("model name") or platform.processor() or platform.machine() or "unknown CPU"
    family = first.get("cpu family")  # x86's model names can be generic on virtual machines
    name = model if family is None else f"{model} (family {family}, model {first.get('model')})"
    parts = [name, f"{cpus} CPU{'s' if cpus != 1 else ''}"]
    flags = set(first.get("flags", "").split())
    vectors = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else ""
    if vectors:
        parts.append(vectors)
    if 2 in caches:
        parts.append(f"L2 {_size(caches[2])} per core")
    if 3 in caches:
        parts.append(f"L3 {_size(caches[3])}")
    return ", ".join(parts)


def _first_processor(cpuinfo: str) -> dict[str, str]:
    """The `key: value` lines of the first processor block of `/proc/cpuinfo`."""
    fields: dict[str, str] = {}
    for line in cpuinfo.splitlines():
        if not line.strip():
            if fields:
                break
            continue
        key, sep, value = line.partition(":")
        if sep:
            fields.setdefault(key.strip(), value.strip())
    return fields


def _cache_sizes() -> dict[int, str]:
    """Data or unified cache size by level for CPU 0, from sysfs ({} where it is missing)."""
    sizes: dict[int, str] = {}
    for index in sorted(CACHE.glob("index*")):
        try:
            kind = (index / "type").read_text().strip()
            level = int((index / "level").read_text())
            size = (index / "size").read_text().strip()
        except (OSError, ValueError):
            continue
        if kind in ("Data", "Unified"):
            sizes[level] = size
    return sizes


def last_level_cache_bytes(caches: dict[int, str] | None = None) -> int | None:
    """The largest cache's size in bytes (of `caches` as sysfs writes them, "2048K", else CPU
    0's), or None where it is not known: what a benchmark must read past to find its data
    back in memory."""
    sizes = _cache_sizes() if caches is None else caches
    if not sizes:
        return None
    sysfs = sizes[max(sizes)]
    if sysfs.endswith("K") and sysfs[:-1].isdigit():
        return int(sysfs[:-1]) * 1024
    if sysfs.endswith("M") and sysfs[:-1].isdigit():
        return int(sysfs[:-1]) * 2**20
    return None


def _size(sysfs: str) -> str:
    """ "2048K" -> "2 MiB", "48K" -> "48 KiB" (sysfs's K is KiB)."""
    if sysfs.endswith("K") and sysfs[:-1].isdigit():
        kib = int(sysfs[:-1])
        return f"{kib // 1024} MiB" if kib % 1024 == 0 else f"{kib} KiB"
    return sysfs


if __name__ == "__main__":
    print(describe())
