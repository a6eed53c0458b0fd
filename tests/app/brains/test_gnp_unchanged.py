"""The neural brain family changed nothing of a GNP run: its file, to the bit."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import h5py
import numpy as np
from lab_fixtures import datasets, tiny_config

from app.phases.implementation import implement
from app.phases.training import train
from app.settings.arenas import shipped_spec
from app.settings.layouts import layout_1
from sim.arena import ArenaSpec

#: sha256 of a tiny CS run's datasets and config, trained and implemented by the code before
#: the lab loop learnt to step neural controllers (commit 8a103b1). A change of the simulator
#: that is meant to change results must update it, saying so.
GNP_RUN_DIGEST = "0681512e7af645c803ad68703475b075b82f3769469b5b891411907065ba690f"


#: Config sections added since that digest, with their defaults (which change no result).
ADDED_SINCE: dict[tuple[str, ...], object] = {
    ("reward",): {"c_from": "true"},
    ("training", "physics"): "pymunk",
    ("training", "noise_stream"): "box-muller-v1",
    # GNP's task settings (#45), at the robot's defaults
    ("controller", "q0"): 0.0,
    ("controller", "tie_break"): "random",
    ("controller", "skip_reward"): "zero",
    ("controller", "threshold_init"): "uniform",
    ("controller", "processing_output"): "parameter",
    ("evolution", "p_add_delete"): 0.0,  # add/delete-node mutation (#45), off
    ("controller", "judgment_branches"): 2,  # multi-way judgment (#45), the thesis's two ways
}


def run_digest(path: Path) -> str:
    """sha256 over every dataset (name, dtype, shape, bytes) and the stored config, less the
    sections added since the digest was taken (at their defaults)."""
    digest = hashlib.sha256()
    for name, values in sorted(datasets(path).items()):
        array = np.ascontiguousarray(values)
        digest.update(f"{name}|{array.dtype.str}|{array.shape}".encode())
        digest.update(array.tobytes())
    with h5py.File(path, "r", locking=False) as handle:
        stored = json.loads(str(handle.attrs["config"]))
    config = layout_1(stored, stored["brain"]["family"])  # the layout the digest was taken in
    for (*parents, key), default in ADDED_SINCE.items():
        where = config
        for parent in parents:
            where = where[parent]
        assert where.pop(key) == default
    for section in ("training", "implementation"):  # arenas carried inline since: by name then
        arena = ArenaSpec.model_validate(config[section]["arena"])
        assert arena == shipped_spec(arena.name)
        config[section]["arena"] = arena.name
    digest.update(json.dumps(config, separators=(",", ":")).encode())
    return digest.hexdigest()


def test_a_gnp_runs_file_data_is_unchanged(tmp_path: Path) -> None:
    config = tiny_config(generations=2)
    path = train(config, tmp_path / "gnp.h5", workers=1)
    implement(path, config.implementation, name="fault", workers=1)
    assert run_digest(path) == GNP_RUN_DIGEST
