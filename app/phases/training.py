"""The training phase of a run, any brain family: `train` a new run file, `resume` a cut one.

The loop is `app.phases.generations`, the same for every family; the family (`app.brains`)
gives generation 0, the run file's shapes, and each next generation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from app.brains.registry import family_of
from app.loop.recording import TraceLayout, life_bytes
from app.phases.generations import (
    Control,
    GenerationSummary,
    Interrupted,
    ProgressCallback,
    TrainingError,
    resume_run,
    start_run,
)
from app.settings.config import RunConfig
from app.store import RunReader, RunTemplate
from app.system.memory import COPIES, check_memory, size_text
from app.system.workers import default_workers

# What callers of the phase meet (its errors, its progress, its stop), imported from their rooms.
__all__ = [
    "Control",
    "GenerationSummary",
    "Interrupted",
    "ProgressCallback",
    "TrainingError",
    "default_workers",
    "resume",
    "train",
]


def train(
    config: RunConfig,
    out: str | Path,
    *,
    workers: int = 1,
    progress: ProgressCallback | None = None,
    local: bool = True,
    control: Control | None = None,
) -> Path:
    """Run the training phase of `config` into a new run file `out`.

    `workers`: processes living each generation (at most one per shard); one is this process
    unless not `local` (the dashboard's, which must stay free to serve the page). `control`
    stops or pauses the run from another thread (the CLI's: Ctrl-C / SIGTERM).

    Raises:
        RunFileError: `out` exists or cannot be created.
        Interrupted: Ctrl-C / SIGTERM / a stop; the file holds every completed generation.
        TrainingError: a worker process died.
    """
    family = family_of(config)
    template = family.run_template()
    check_training_memory(template, family.trace_layout)
    return start_run(config, out, template, family.first, workers, local, progress, control)


def resume(
    path: str | Path,
    *,
    workers: int = 1,
    progress: ProgressCallback | None = None,
    local: bool = True,
    control: Control | None = None,
) -> Path:
    """Continue an interrupted run from its last checkpoint; the result matches an
    uninterrupted run of the same config and seed. `workers`, `local` and `control` as for
    `train`.

    Raises:
        RunFileError: not a resumable run (for a neural run also: replaying its optimiser does
            not give the checkpointed population).
    """
    with RunReader(path) as run:
        family = family_of(run.config)
    check_training_memory(family.run_template(), family.trace_layout)
    return resume_run(path, family.rebuild, workers, local, progress, control)


def check_training_memory(template: RunTemplate, layout: TraceLayout) -> None:
    """Refuse a run whose population cannot be held in this machine's memory (`COPIES` copies
    of it, and the elite's recorded life), before any of it is allocated.

    Raises:
        TrainingError: one line giving the memory needed and available.
    """
    training = template.config.training
    individual = sum(np.asarray(a).nbytes for a in template.genome.values())
    life = life_bytes(1, training.steps, layout)
    needed = COPIES * training.population * individual + life
    what = f"training {training.population} individuals of {size_text(individual)}"
    check_memory(needed, what, TrainingError)
