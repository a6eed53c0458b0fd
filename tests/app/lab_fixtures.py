"""Helpers of the lab's tests: tiny configs, file digests, dataset comparison, CLI errors,
gnp-lab processes (started, killed, their children's fate), waiting on a run's progress."""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import psutil
import pytest

from app.settings.config import RunConfig
from app.settings.loading import build_config
from app.store import RunReader


def tiny_config(**training: Any) -> RunConfig:
    """A run small enough for tests: 12 individuals in 3 worlds, 60 steps, 3 generations."""
    settings = {"population": 12, "steps": 60, "generations": 3, "shard_size": 5}
    settings.update(training)
    return build_config(
        {
            "seed": 7,
            "training": settings,
            "implementation": {
                "steps": 120,
                "repeats": 1,
                "fault_step": 60,
                "broken_sensors": [2, 3],
                "recorded_trials": 2,
            },
        }
    )


def file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def datasets(path: Path) -> dict[str, np.ndarray]:
    """Every dataset of an HDF5 file (read in SWMR mode, so killed runs open too)."""
    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r", swmr=True, locking=False) as handle:
        handle.visititems(
            lambda name, obj: (
                out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None
            )
        )
    return out


def assert_same_data(a: Path, b: Path, skip: tuple[str, ...] = ()) -> None:
    """Both files hold the same datasets with identical values (NaN equal to NaN)."""
    left, right = datasets(a), datasets(b)
    assert sorted(left) == sorted(right)
    for name in left:
        if name.startswith(skip):
            continue
        assert left[name].dtype == right[name].dtype, name
        assert np.array_equal(left[name], right[name], equal_nan=left[name].dtype.kind == "f"), name


def one_error_line(capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    """The one `gnp-lab: error:` line the command wrote to stderr (and nothing else), holding
    every one of `needles`."""
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("gnp-lab: error: "), err
    for needle in needles:
        assert needle in lines[0], err
    return lines[0]


ROOT = Path(__file__).resolve().parents[2]


def gnp_lab(*args: str | Path, env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
    """`gnp-lab ARGS` in a process of its own, in its own process group (`env`: variables set
    beside this process's)."""
    return python("-m", "app.cli", *args, env=env)


def python(*args: str | Path, env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
    """`python ARGS` (this interpreter, the repository importable) in its own process group:
    a test's cleanup can kill the group, though a test's kill hits the process alone."""
    return subprocess.Popen(
        [sys.executable, *map(str, args)],
        cwd=ROOT,
        env=dict(os.environ, PYTHONPATH=str(ROOT), **(env or {})),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )


def finish(process: subprocess.Popen[bytes], timeout: float = 240) -> tuple[int, str]:
    """`process`'s exit status and standard error, once it ends (killed after `timeout` s)."""
    try:
        _, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        _, err = process.communicate()
        raise AssertionError(f"timed out: {err.decode()[-3000:]}") from None
    return process.returncode, err.decode()


def _lives(process: psutil.Process) -> bool:
    """Running, and not a zombie (an orphan its new parent has not reaped yet is gone)."""
    try:
        return process.is_running() and process.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def kill_alone(process: subprocess.Popen[bytes], within: float = 3.0) -> list[int]:
    """SIGKILL `process` alone, as `kill -9 PID` does (not its process group); the ids of
    its descendants of that moment still alive `within` seconds later (killed then)."""
    children = psutil.Process(process.pid).children(recursive=True)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()  # not communicate(): a surviving child would hold its pipes open
    deadline = time.monotonic() + within
    while any(map(_lives, children)) and time.monotonic() < deadline:
        time.sleep(0.05)
    alive = [child for child in children if _lives(child)]
    for child in alive:
        child.kill()
    for pipe in (process.stdout, process.stderr):
        if pipe is not None:
            pipe.close()
    return [child.pid for child in alive]


def children_of(process: subprocess.Popen[bytes]) -> int:
    """How many descendants `process` has now."""
    try:
        return len(psutil.Process(process.pid).children(recursive=True))
    except psutil.NoSuchProcess:
        return 0


def generations_done(path: Path) -> int:
    """How many generations the run file at `path` holds; -1 while it cannot be read (not
    there yet, or being replaced by a resume)."""
    try:
        with RunReader(path) as run:
            return run.generations_done
    except Exception:
        return -1


def wait_for(condition: Callable[[], object], timeout: float = 180) -> None:
    """Poll `condition` until it is true; fail after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)
