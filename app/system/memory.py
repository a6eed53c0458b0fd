"""Memory a command will need, checked against what the machine has before anything is allocated:
a population or a batch of episodes too large for the machine ends on one line giving both
figures, instead of dying half-way in numpy (or in the kernel's OOM killer)."""

from __future__ import annotations

import os
from pathlib import Path

MEMINFO = Path("/proc/meminfo")
CGROUP_LIMIT = Path("/sys/fs/cgroup/memory.max")
CGROUP_USED = Path("/sys/fs/cgroup/memory.current")

COPIES = 4
"""Copies of a population's arrays held at once while training: the population, its offspring,
a checkpoint being written and the workers' shards."""


def available_memory() -> int | None:
    """Bytes this process could allocate without swapping: Linux's MemAvailable (else the free
    physical pages), within the cgroup's limit if one is set; None when nothing says."""
    found = _meminfo_available()
    if found is None:
        try:
            found = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError):
            found = None
    room = _cgroup_room()
    if room is not None:
        found = room if found is None else min(found, room)
    return found


def _meminfo_available() -> int | None:
    try:
        lines = MEMINFO.read_text().splitlines()
    except OSError:
        return None
    for line in lines:
        name, _, value = line.partition(":")
        if name == "MemAvailable" and value.split()[:1] and value.split()[0].isdigit():
            return int(value.split()[0]) * 1024
    return None


def _cgroup_room() -> int | None:
    try:
        limit, used = CGROUP_LIMIT.read_text().strip(), CGROUP_USED.read_text().strip()
    except OSError:
        return None
    if not (limit.isdigit() and used.isdigit()):  # "max": no limit
        return None
    return max(0, int(limit) - int(used))


def size_text(n_bytes: float) -> str:
    """A size for people: "57.2 GiB", "512.0 MiB"."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(n_bytes) < 1024 or unit == "TiB":
            return f"{n_bytes:.1f} {unit}" if unit != "B" else f"{int(n_bytes)} B"
        n_bytes /= 1024
    raise AssertionError("unreachable")


def check_memory(needed: int, what: str, error: type[Exception]) -> None:
    """Refuse `what` (e.g. "training 100000 individuals") if it needs more than the machine has.

    Raises:
        error: one line giving the memory needed and the memory available.
    """
    available = available_memory()
    if available is not None and needed > available:
        raise error(
            f"{what} needs about {size_text(needed)} of memory; this machine has "
            f"{size_text(available)} available"
        )
