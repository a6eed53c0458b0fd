"""File safety: whole files only, one writer at a time, clear errors for files that are not runs.

A run file only ever appears at its final path fully formed, and a change that adds objects
rewrites a copy and renames it over the original (`atomic_file`), so a crash at any moment leaves
the old file or the new one, never half of either.

A SWMR writer killed by SIGKILL leaves the file's consistency flags set: HDF5 then refuses plain
opens ("file is already open for write") but SWMR reads work, so `open_for_read` falls back to a
SWMR read.
"""

from __future__ import annotations

import contextlib
import fcntl
import glob
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO

import h5py

from app.settings.user_files import check_regular
from app.system.signals import process_alive

# The HDF5 1.10 file format: the oldest with SWMR, and what h5dump of Debian 12 (1.10.8) reads.
LIBVER = ("v110", "v110")
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


class RunFileError(Exception):
    """A run file or name is missing, foreign, corrupt, or cannot be used as asked."""


@contextlib.contextmanager
def atomic_file(path: Path, *, overwrite: bool) -> Iterator[Path]:
    """Yield a temporary path beside `path`; when the block succeeds, it becomes `path`.

    Write the whole new file at the yielded path. On success it is renamed over `path`
    (`overwrite=True`) or linked to `path`, failing with FileExistsError if `path` exists
    (`overwrite=False`). On any failure `path` is left as it was and the temporary file is
    removed. An HDF5 handle may stay open across the rename: it follows the file, not the name.
    """
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        yield tmp
        if overwrite:
            os.replace(tmp, path)
        else:
            os.link(tmp, path)  # unlike a rename, refuses to replace an existing file
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def create_file(path: Path) -> h5py.File:
    """A new, empty HDF5 file at `path` in the format run files use (see LIBVER)."""
    return h5py.File(path, "w", libver=LIBVER, locking=False)


class WriterLock:
    """An advisory lock (`.NAME.h5.lock` beside the run) held by whoever writes the run.

    Readers never take it. The kernel drops it when its holder dies, even by SIGKILL, so a
    killed run can be resumed while a live (or paused) one cannot get a second writer. The
    holder removes the lock file when it releases the lock, and clears the temporary files
    (`.NAME.h5.PID.tmp`) that a killed writer of the same run left (only a lock holder writes
    them, so while it holds the lock no other one is in use).

    Raises:
        RunFileError: another process holds the lock, or the folder cannot be written.
    """

    def __init__(self, path: Path) -> None:
        self._path = writer_lock_path(path)
        try:
            handle = take_lock(self._path)
        except OSError as error:
            raise RunFileError(f"cannot write beside {path}: {error.strerror}") from None
        if handle is None:
            raise RunFileError(
                f"{path.name} is being written by another gnp-lab process (training, resume "
                "or implementation); wait for it to finish or stop it"
            )
        self._handle = handle
        remove_temporaries(path, keep_pid=os.getpid())

    def release(self) -> None:
        release_lock(self._path, self._handle)


Stamp = tuple[int, int, int, int]
"""A file's inode, size, modification and change times (ns): what a write changes."""

SETTLED_SECONDS = 2.0
"""A file last written this long ago is not being written: a stamp that has not changed since
means the file has not (two writes in one tick of the file system's clock look alike)."""


def stamp(path: Path) -> Stamp | None:
    """`path`'s stamp, or None if it is gone."""
    try:
        info = os.stat(path)
    except OSError:
        return None
    return info.st_ino, info.st_size, info.st_mtime_ns, info.st_ctime_ns


def settled(mark: Stamp) -> bool:
    """Whether the file `mark` stamps was last written `SETTLED_SECONDS` ago or more: until
    then, the same stamp does not tell that the file is unchanged."""
    return time.time() - mark[2] / 1e9 >= SETTLED_SECONDS


def writer_lock_path(path: Path) -> Path:
    """The lock file of run file `path`'s writer (`WriterLock`): `.NAME.h5.lock` beside it."""
    return path.with_name(f".{path.name}.lock")


def remove_stale_lock(lock_path: Path) -> bool:
    """Remove lock file `lock_path` if no process holds its lock (its holder was killed after
    the run was complete: no later writer comes to take it over); True if removed."""
    handle = take_lock(lock_path)
    if handle is None:  # held: a live writer's
        return False
    release_lock(lock_path, handle)
    return True


def take_lock(lock_path: Path) -> IO[str] | None:
    """Open `lock_path` and take its exclusive advisory lock without waiting: the open file,
    or None when another holds it. Retries while the file was removed between the open and
    the lock (its holder released it), so two processes never hold different files.

    Raises:
        OSError: the file cannot be created.
    """
    while True:
        handle = lock_path.open("a+")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            return None
        try:
            same = os.path.samestat(os.fstat(handle.fileno()), os.stat(lock_path))
        except FileNotFoundError:
            same = False
        if same:
            return handle
        handle.close()


def release_lock(lock_path: Path, handle: IO[str]) -> None:
    """Remove the lock file, then release its lock (no lock file is left behind)."""
    if handle.closed:
        return
    # Unlinked while still locked: whoever opened it meanwhile finds it gone once it gets the
    # lock, and starts over on a new file (see `take_lock`).
    with contextlib.suppress(FileNotFoundError):
        lock_path.unlink()
    fcntl.flock(handle, fcntl.LOCK_UN)
    handle.close()


def remove_temporaries(path: Path, keep_pid: int | None = None) -> list[Path]:
    """Remove the temporary files (`.NAME.PID.tmp`, see `atomic_file`) that writers of `path`
    left when they were killed: those of processes that no longer run, or, for the holder of
    `path`'s writer lock (`keep_pid`, its own pid), all others. Returns what was removed."""
    removed = []
    for tmp in path.parent.glob(f".{glob.escape(path.name)}.*.tmp"):
        pid_text = tmp.name[len(path.name) + 2 : -len(".tmp")]
        if not pid_text.isdigit() or int(pid_text) == keep_pid:
            continue
        if keep_pid is None and process_alive(int(pid_text)):
            continue
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
            removed.append(tmp)
    return removed


def open_for_read(path: Path) -> h5py.File:
    """Open an HDF5 file for reading, also while (or after) a SWMR writer held it.

    A live writer's file can be shorter than the end-of-file address its superblock already
    names (space allocated, its data not yet written): for a moment it reads as truncated. So a
    short file is tried again for up to `SETTLE_SECONDS` before it is called truncated.

    Raises:
        RunFileError: the file is missing, not a regular file, not HDF5, truncated or otherwise
            unreadable.
    """
    check_regular(path, RunFileError, "run file")
    if not h5py.is_hdf5(path):
        raise RunFileError(f"not an HDF5 file: {path}")
    deadline = time.monotonic() + SETTLE_SECONDS
    while True:
        try:
            return _open(path)
        except _ShortFile:
            if time.monotonic() >= deadline:
                raise RunFileError(f"corrupt run file {path}: truncated") from None
            time.sleep(0.02)


SETTLE_SECONDS = 1.0
"""How long a reader waits for a short run file to reach its end-of-file address."""


class _ShortFile(Exception):
    """The file ends before the end-of-file address in its superblock."""


def _open(path: Path) -> h5py.File:
    try:
        return h5py.File(path, "r", locking=False)
    except OSError as error:
        if "truncated file" in str(error):
            raise _ShortFile from None
        if "already open for write" not in str(error):
            raise RunFileError(f"cannot open {path}: {error}") from None
    # A SWMR writer is live, or was killed: only a SWMR read opens the file. It skips HDF5's
    # end-of-file check (the file grows), and on a truncated file it would retry reads for a
    # long time, so check the length against the superblock first.
    _check_length(path)
    try:
        return h5py.File(path, "r", libver=LIBVER, swmr=True, locking=False)
    except OSError as error:
        raise RunFileError(f"cannot open {path}: {error}") from None


def _check_length(path: Path) -> None:
    """Refuse a file shorter than the end-of-file address in its (v2/v3) superblock."""
    with path.open("rb") as handle:
        head = handle.read(48)
    if head[:8] != _HDF5_SIGNATURE or head[8] < 2 or head[9] != 8:
        return  # a superblock this check does not parse (not written by gnp-lab)
    stored_eof = int.from_bytes(head[28:36], "little")
    if path.stat().st_size < stored_eof:
        raise _ShortFile
