"""Helpers of the lab's tests: tiny configs, file digests, dataset comparison, CLI errors."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest

from app.config import RunConfig, build_config


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
