"""Every seed derivation of the lab, in one place.

Each random draw comes from a `numpy.random.SeedSequence` keyed by the run's seed, a purpose tag
and the indices that identify what is drawn for (generation, individual, trial), never by a
position in a batch or a worker. That is what makes a run bit-identical on any number of worker
processes or machines, and an experiment's arms meet the same start poses, noise and broken
sensors for the same seed (common random numbers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Purpose tags mixed into every SeedSequence so different uses never share a stream.
_TAG_INIT, _TAG_LIFE, _TAG_EVOLVE, _TAG_TRIAL, _TAG_BROKEN = 1, 2, 3, 4, 5
_TAG_OPTIMISER = 6


@dataclass(frozen=True)
class LifeSeeds:
    """Random inputs of N lives: all drawn per individual, none from a batch position."""

    world: np.ndarray  # (N,) uint64 seed of each robot's stream (noise, faults)
    engine: np.ndarray  # (N,) uint64 seed of each controller's stream
    starts: np.ndarray  # (N, S) start pose index of each of the S segments of a life

    def take(self, sl: slice) -> LifeSeeds:
        return LifeSeeds(self.world[sl], self.engine[sl], self.starts[sl])


def n_segments(steps: int, redraw_every: int) -> int:
    """How many start poses a life of `steps` uses when redrawn every `redraw_every` steps."""
    return 1 if redraw_every <= 0 else math.ceil(steps / redraw_every)


def _states(keys: list[list[int]], words: int) -> np.ndarray:
    """(len(keys), words) uint64 words, one SeedSequence per key."""
    return np.array(
        [np.random.SeedSequence(key).generate_state(words, np.uint64) for key in keys],
        dtype=np.uint64,
    ).reshape(len(keys), words)


def life_seeds(
    seed: int, generation: int, indices: np.ndarray, segments: int, n_starts: int
) -> LifeSeeds:
    """Seeds of individuals `indices` of `generation`, keyed by (seed, generation, index)."""
    states = _states([[seed, _TAG_LIFE, generation, int(i)] for i in indices], 2 + segments)
    return LifeSeeds(
        world=states[:, 0] >> np.uint64(1),
        engine=states[:, 1] >> np.uint64(1),
        starts=(states[:, 2:] % np.uint64(n_starts)).astype(np.int64),
    )


def init_rng(seed: int) -> np.random.Generator:
    """The Generator that draws generation 0."""
    return np.random.default_rng(np.random.SeedSequence([seed, _TAG_INIT]))


def evolution_rng(seed: int, generation: int) -> np.random.Generator:
    """The Generator evolution uses after `generation`."""
    return np.random.default_rng(np.random.SeedSequence([seed, _TAG_EVOLVE, generation]))


def optimiser_seed(seed: int) -> int:
    """The seed of a neural optimiser's own stream (pycma's sampler, NEAT's `random.Random`)."""
    return int(np.random.SeedSequence([seed, _TAG_OPTIMISER]).generate_state(1, np.uint64)[0] >> 1)


def trial_seeds(seed: int, trials: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(world seeds, engine seeds) of implementation trials, uint64 each, keyed by (seed, trial)."""
    states = _states([[seed, _TAG_TRIAL, int(i)] for i in trials], 2)
    return states[:, 0] >> np.uint64(1), states[:, 1] >> np.uint64(1)


def broken_sensor_draws(seed: int, trials: np.ndarray, k: int, n_sensors: int) -> np.ndarray:
    """(len(trials), k) sorted sensor indices that break in each trial, drawn uniformly without
    replacement from a stream keyed by (seed, trial): the same for every arm of an experiment."""
    draws = [
        np.sort(
            np.random.default_rng([seed, _TAG_BROKEN, int(i)]).choice(n_sensors, k, replace=False)
        )
        for i in trials
    ]
    return np.array(draws, dtype=np.int64).reshape(len(trials), k)
