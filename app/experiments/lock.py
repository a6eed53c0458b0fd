"""One `experiment run` per experiment folder at a time.

The lock is `experiments/NAME/.run.lock`, filelock's advisory lock (flock) holding the holder's
pid and the scale it runs (what the dashboard reads to show a run in another terminal). The
kernel drops it when its holder dies (even by SIGKILL); the holder removes the file when it
ends, while it still holds it (filelock's acquire starts over on a file removed meanwhile, so
two processes never hold different files). Taking it also clears the temporary files
(`.*.PID.tmp`) and the run files' writer locks (`.NAME.h5.lock`, held by no one) that killed
runs left in the folder.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from filelock import FileLock, Timeout

from app.experiments.spec import ExperimentError
from app.store.files import remove_stale_lock, remove_temporaries, writer_lock_path
from app.system.signals import process_alive

LOCK_NAME = ".run.lock"


@contextmanager
def experiment_lock(folder: str | Path, scale: str = "") -> Iterator[None]:
    """Hold the lock of the experiment folder `folder` (created if missing) meanwhile, running
    `scale`.

    Raises:
        ExperimentError: another process runs this experiment ("already running (pid N)"), or
            the folder cannot be written.
    """
    folder = Path(folder)
    path = folder / LOCK_NAME
    lock = FileLock(path, timeout=0, on_acquired=functools.partial(_write_holder, scale=scale))
    try:
        folder.mkdir(parents=True, exist_ok=True)
        lock.acquire()
    except Timeout:  # before OSError: filelock's Timeout is a TimeoutError
        raise ExperimentError(
            f"experiment {folder.name!r} is already running ({_holder(path)}); wait for it to "
            "finish or stop it, then run the same command to go on"
        ) from None
    except OSError as error:
        raise ExperimentError(f"cannot write in {folder}: {error.strerror}") from None
    try:
        for scale_dir in (folder, *(p for p in folder.iterdir() if p.is_dir())):
            for leftover in scale_dir.glob(".*.tmp"):
                remove_temporaries(leftover.with_name(_target_name(leftover.name)))
            # A run killed once complete, before it removed its lock file: no resume of it
            # comes to take the lock over.
            for run in scale_dir.glob("*.h5"):
                if writer_lock_path(run).exists():
                    remove_stale_lock(writer_lock_path(run))
        yield
    finally:
        path.unlink(missing_ok=True)  # while held: no lock file is left behind
        lock.release()


def holder_elsewhere(folder: str | Path) -> tuple[int, str] | None:
    """(pid, scale) of another live process that holds experiment folder `folder`'s lock (an
    `experiment run` in another terminal), as it wrote them; None when no other does. Read
    without taking the lock, so a run starting meanwhile is never refused for it."""
    pid, scale = _written(Path(folder) / LOCK_NAME)
    if pid is None or pid == os.getpid() or not process_alive(pid):
        return None  # nobody, a holder starting now (the next look sees it), ours, or stale
    return pid, scale


def _write_holder(fd: int, scale: str) -> None:
    """Write the holder's pid and scale into the lock file it has just taken."""
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n{scale}\n".encode() if scale else f"{os.getpid()}\n".encode())


def _written(path: Path) -> tuple[int | None, str]:
    """The pid (None if not yet written) and scale a lock file holds."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):  # none, or not one a holder wrote
        return None, ""
    pid = int(lines[0]) if lines and lines[0].strip().isdigit() else None
    return pid, lines[1].strip() if len(lines) > 1 else ""


def _holder(path: Path) -> str:
    """`pid N` of the lock's holder, as it wrote it (it may not have written it yet)."""
    pid, _ = _written(path)
    return "pid not yet written" if pid is None else f"pid {pid}"


def _target_name(tmp_name: str) -> str:
    """The file a temporary `.NAME.PID.tmp` was to become: NAME."""
    return tmp_name[1:].removesuffix(".tmp").rpartition(".")[0]
