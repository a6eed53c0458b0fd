"""Disk space: refuse a write the disk cannot hold before HDF5 starts it.

HDF5 (2.0, through h5py 3.16) does not survive a full disk: a failed write leaves the open
file in a state where every later flush, close and even garbage collection fails again, and
the process ends in a segmentation fault at exit. So every writer asks first whether the free
space covers an upper bound of what it is about to add (uncompressed sizes, whole chunks, and
`MARGIN` for HDF5's metadata), and stops cleanly when it does not: the file keeps what it had
(a training run stays resumable).
"""

from __future__ import annotations

import errno
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.store.files import RunFileError
from app.store.schema import Placed, RunTemplate, layout_of, place

MARGIN = 64 * 1024
"""Bytes kept free beyond a write's data: HDF5 metadata (object headers, B-trees, heaps)."""


class DiskFullError(RunFileError):
    """The disk cannot hold what a writer is about to add; nothing was written."""


def free_bytes(folder: Path) -> int:
    """Bytes an unprivileged process may still write on `folder`'s file system."""
    stats = os.statvfs(folder)
    return stats.f_bavail * stats.f_frsize


def require_space(folder: Path, need: int, what: str) -> None:
    """Raise DiskFullError unless `folder`'s disk has `need` + `MARGIN` bytes free.

    Args:
        folder: an existing folder on the disk written to.
        need: an upper bound of the bytes about to be written.
        what: what is about to be written, for the message ("generation 7 of run.h5").
    """
    free = free_bytes(folder)
    if free < need + MARGIN:
        raise DiskFullError(
            f"no space left on the disk of {folder} for {what}: {_size(free)} free, about "
            f"{_size(need + MARGIN)} needed"
        )


def _size(count: int) -> str:
    for unit in ("bytes", "KiB", "MiB", "GiB"):
        if count < 1024 or unit == "GiB":
            return f"{count:.0f} {unit}" if unit == "bytes" else f"{count:.1f} {unit}"
        count /= 1024  # type: ignore[assignment]
    raise AssertionError  # pragma: no cover


def _bytes(datasets: Iterable[Placed], rows: int | None = None) -> int:
    """Uncompressed bytes of `datasets`, or of `rows` rows of each along its first axis."""
    total = 0
    for d in datasets:
        shape = d.shape if rows is None or not d.shape else (min(rows, d.shape[0]), *d.shape[1:])
        total += int(np.prod(shape, dtype=np.int64)) * d.dtype.itemsize
    return total


@dataclass(frozen=True)
class RunGrowth:
    """Upper bounds of what a training run's file grows by, in bytes."""

    chunks: tuple[tuple[int, int], ...]  # per-generation datasets: (rows per chunk, chunk bytes)
    slot: int  # a checkpoint slot's first write (its storage is allocated then)
    elite: int  # the last generation's elite life

    def generation(self, g: int) -> int:
        """Generation `g`'s rows: a dataset's chunk is allocated by its first row."""
        return sum(size for rows, size in self.chunks if g % rows == 0)


def run_growth(template: RunTemplate) -> RunGrowth:
    """The growth bounds of a run of `template` (see `RunGrowth`)."""
    dims = template.dims()
    placed = place(layout_of(template.kind), dims, template.arrays())
    chunks = []
    for d in placed:
        if d.row.shape[:1] == ("generations",):
            rows = d.row.chunk_rows
            count = min(d.shape[0], dims[rows] if isinstance(rows, str) else rows or d.shape[0])
            chunks.append((count, _bytes([d], count)))
    slot = [d for d in placed if d.path.startswith("checkpoint/slot0/")]
    elite = [d for d in placed if d.path.startswith("elite/")]
    return RunGrowth(tuple(chunks), _bytes(slot), _bytes(elite))


def file_size(path: Path) -> int:
    """The size of `path` in bytes (0 when it is missing)."""
    try:
        return path.stat().st_size
    except FileNotFoundError:
        return 0


def is_disk_full(error: BaseException) -> bool:
    """Whether `error` is a write that failed on a full disk (h5py reports ENOSPC in its text)."""
    return getattr(error, "errno", None) == errno.ENOSPC or "errno = 28" in str(error)
