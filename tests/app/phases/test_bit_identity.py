"""The lab's numbers reproduce to the digit: the committed demo's stored lives, and small runs.

Speed work (culled ray casts, fused kernels, worker scheduling) must not move a single bit:
the committed reports' values were computed by the code as it was. Two oracles:
- `saved_runs/demo.h5` stores the first recorded trials of its implementation phases, every
  step of them. A trial's life depends only on (seed, trial index), so re-living trials 0..9
  for the first steps must give back exactly those poses, readings, observations, commands and
  reward terms (noise σ = 50 and a dead sensor included: the noise stream and the faults).
- `fingerprints.json` holds digests (see `fingerprints.py`) of a small training run and
  implementation phase computed by the code before the speed work (random faults, noise and
  several worlds per phase).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fingerprints import implementation_digests, training_digests

import sim
from app.brains.registry import family_of
from app.phases.implementation import run_implementation
from app.store import RunReader

DEMO = Path(__file__).parents[3] / "saved_runs" / "demo.h5"
FINGERPRINTS = json.loads((Path(__file__).parents[1] / "fingerprints.json").read_text())
STEPS = 700  # past the demo's fault step (500), noise and faults both replayed


with RunReader(DEMO) as _demo:  # whichever implementations the committed demo stores
    DEMO_IMPLEMENTATIONS = _demo.implementation_names()


def test_the_demo_stores_implementations_to_replay() -> None:
    assert DEMO_IMPLEMENTATIONS  # else the replay test below checks nothing


@pytest.mark.parametrize("name", DEMO_IMPLEMENTATIONS)
def test_demo_implementation_trials_replay_to_the_bit(name: str) -> None:
    with RunReader(DEMO) as run:
        stored = run.implementation(name)
        family = family_of(run.config)
        individual = family.best(run, stored.generation)
        seed = stored.settings.seed if stored.settings.seed is not None else run.seed
        control_period = run.config.training.control_period
    steps = min(STEPS, stored.settings.steps)
    settings = stored.settings.model_copy(update={"repeats": 1, "steps": steps})
    again = run_implementation(
        family,
        individual,
        settings,
        seed=seed,
        control_period=control_period,
        name=name,
        generation=stored.generation,
    )
    old, new = stored.trials, again.trials
    for field in ("poses", "readings", "observations", "commands"):
        assert np.array_equal(getattr(new, field), getattr(old, field)[:, :steps]), field
    for term, values in old.terms.items():
        assert np.array_equal(new.terms[term], values[:, :steps]), term
    for key, values in old.trace.items():
        assert np.array_equal(new.trace[key], values[:, :steps]), key


# The analytic world's poses are pymunk's bit for bit, and GNP controllers in it run the compiled
# loop (app.loop.fused): the same digests pin that loop to the code before the speed work too.
PHYSICS = ["pymunk", "analytic"]


@pytest.mark.parametrize("physics", PHYSICS)
def test_a_small_training_run_reproduces_the_committed_fingerprints(physics: sim.Physics) -> None:
    digests = training_digests(physics=physics)
    assert digests == {k: FINGERPRINTS[k] for k in digests}


@pytest.mark.parametrize("physics", PHYSICS)
@pytest.mark.parametrize("workers", [1, 2])
def test_a_small_implementation_reproduces_the_committed_fingerprint(
    workers: int, physics: sim.Physics
) -> None:
    expected = {"implementation": FINGERPRINTS["implementation"]}
    assert implementation_digests(workers, physics) == expected
