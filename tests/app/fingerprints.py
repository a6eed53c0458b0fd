"""Digests of a small training run and implementation phase, to pin the lab's numbers.

    python tests/app/fingerprints.py > tests/app/fingerprints.json

writes the digests of the code as it is; `test_bit_identity.py` recomputes them. The committed
file was written before the speed work of issue #19 (culled sensors, worker scheduling), so the
test shows that work moved no bit. Regenerate it only for a change meant to alter results.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from pathlib import Path

import numpy as np

from app.brains.registry import family_of
from app.phases.implementation import run_implementation
from app.phases.training import train
from app.settings.config import ImplementationSettings, RunConfig
from app.settings.loading import build_config
from app.store import RunReader
from sim import Physics


def digest(arrays: dict[str, np.ndarray]) -> str:
    """sha256 of the arrays' names, dtypes, shapes and bytes, in name order."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def run_config(physics: Physics = "pymunk") -> RunConfig:
    """Small CS training with noise and episode redraws: every part of the loop runs."""
    return build_config(
        {},
        {
            "controller": {"method": "CS"},
            "training": {
                "population": 24,
                "generations": 3,
                "steps": 200,
                "redraw_every": 100,
                "noise_sigma": 50.0,
                "physics": physics,
            },
        },
    )


IMPLEMENTATION = ImplementationSettings(
    steps=300,
    repeats=2,
    noise_sigma=20.0,
    break_count=2,
    fault_mode="random",
    fault_step=100,
    recorded_trials=3,
)
"""Random faults on two sensors drawn per trial, noise, and two worlds of trials."""


def training_digests(workers: int = 1, physics: Physics = "pymunk") -> dict[str, str]:
    """Digests of the small run's history, best genomes and elite life."""
    with tempfile.TemporaryDirectory() as folder:
        path = train(run_config(physics), Path(folder) / "run.h5", workers=workers)
        with RunReader(path) as run:
            history = run.history()
            elite = run.elite()
            assert elite is not None
            genomes = {
                f"{g}/{name}": array
                for g in range(run.generations_done)
                for name, array in run.best_genome_arrays(g).items()
            }
    table = {
        name: getattr(history, name)
        for name in ("best_fitness", "mean_fitness", "std_fitness", "best_index", "fitness")
    }
    life = {
        "poses": elite.poses,
        "readings": elite.readings,
        "observations": elite.observations,
        "commands": elite.commands,
        **{f"terms/{k}": v for k, v in elite.terms.items()},
    }
    return {"history": digest(table), "genomes": digest(genomes), "elite": digest(life)}


def implementation_digests(workers: int = 1, physics: Physics = "pymunk") -> dict[str, str]:
    """Digests of an implementation phase of the small run's generation-0 best."""
    with tempfile.TemporaryDirectory() as folder:
        config = run_config(physics)
        path = train(
            build_config(config.model_dump(), {"training": {"generations": 1}}),
            Path(folder) / "run.h5",
        )
        with RunReader(path) as run:
            family = family_of(run.config)
            individual = family.best(run, 0)
    result = run_implementation(
        family,
        individual,
        IMPLEMENTATION,
        seed=7,
        control_period=config.training.control_period,
        name="fingerprint",
        generation=0,
        workers=workers,
        physics=physics,
    )
    trials = result.trials
    return {
        "implementation": digest(
            {
                "reward_per_step": result.reward_per_step,
                "trial_mean_reward": result.trial_mean_reward,
                "trial_mean_after_fault": result.trial_mean_after_fault,
                "poses": trials.poses,
                "readings": trials.readings,
                "observations": trials.observations,
                "commands": trials.commands,
            }
        )
    }


if __name__ == "__main__":
    print(json.dumps({**training_digests(), **implementation_digests()}, indent=2))
