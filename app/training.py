"""The training phase of a run, either brain family: `train` a new run file, `resume` a cut one.

The loop is `app.generations` (the same for every family); this module holds the GNP brain:
generation 0 drawn from (seed, init), lives that learn online with ε and α fixed or scheduled
(Eq. 4.1-4.2), and evolution's Generator from (seed, generation). A config with a `neuro`
section trains a net instead (`app.neuro_training`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import gnp
from app.config import RunConfig, TrainingSettings
from app.generations import (
    Control,
    GenerationSummary,
    Interrupted,
    ProgressCallback,
    TrainingError,
    resume_run,
    start_run,
)
from app.seeds import evolution_rng, init_rng
from app.store import RunReader, RunTemplate
from app.workers import default_workers

# What callers of the phase meet (its errors, its progress, its stop), imported from their rooms.
__all__ = [
    "Control",
    "GenerationSummary",
    "Interrupted",
    "ProgressCallback",
    "TrainingError",
    "default_workers",
    "generation_epsilon_alpha",
    "initial_population",
    "resume",
    "run_template",
    "train",
]


def initial_population(config: RunConfig) -> gnp.Population:
    """Generation 0, drawn from (seed, init)."""
    return gnp.init_population(
        config.controller.gnp_config(), config.training.population, init_rng(config.seed)
    )


def generation_epsilon_alpha(training: TrainingSettings, generation: int) -> tuple[float, float]:
    """(ε, α) of a generation: fixed, or Eq. 4.1-4.2."""
    eps_schedule, alpha_schedule = training.schedules()
    return gnp.epsilon_alpha_over_generations(
        eps_schedule, alpha_schedule, generation, training.generations, training.schedule_progress
    )


class GnpBrain:
    """A GNP population for `app.generations`: evolved from its learned self each generation."""

    def __init__(self, config: RunConfig, pop: gnp.Population) -> None:
        self._config = config
        self._cfg = config.controller.gnp_config()
        self._pop = pop

    @classmethod
    def first(cls, config: RunConfig) -> GnpBrain:
        return cls(config, initial_population(config))

    @classmethod
    def rebuild(
        cls, config: RunConfig, generation: int, arrays: dict[str, np.ndarray], fitness: np.ndarray
    ) -> GnpBrain:
        return cls(config, gnp.population_from_arrays(config.controller.gnp_config(), arrays))

    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        return generation_epsilon_alpha(self._config.training, generation)

    def individuals(self) -> gnp.Population:
        return self._pop

    def arrays(self, individuals: gnp.Population) -> dict[str, np.ndarray]:
        return gnp.population_to_arrays(individuals)

    def advance(
        self, learned: gnp.Population, fitness: np.ndarray, generation: int
    ) -> dict[str, np.ndarray]:
        training = self._config.training
        self._pop = gnp.evolve(
            self._cfg,
            learned,
            fitness,
            generation,
            training.generations,
            evolution_rng(self._config.seed, generation),
            self._config.evolution,
        )
        return gnp.population_to_arrays(self._pop)


def run_template(config: RunConfig) -> RunTemplate:
    """The shapes and dtypes a run file of this config needs: one individual's genome and
    one step's trace of one controller."""
    cfg = config.controller.gnp_config()
    genome = {
        name: np.zeros((1, *shape), gnp.field_dtype(name))
        for name, shape in gnp.field_shapes(cfg).items()
    }
    trace = {
        name: np.zeros((1, *shape), gnp.TRACE_DTYPE)
        for name, shape in gnp.trace_shapes(cfg).items()
    }
    return RunTemplate(config=config, genome=genome, trace=trace)


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
    if config.neuro is not None:  # a neural brain (CMA-ES, NEAT)
        from app.neuro_training import NetBrain, neural_template

        net = neural_template(config)
        return start_run(config, out, net, NetBrain.first, workers, local, progress, control)
    gnp_file = run_template(config)
    return start_run(config, out, gnp_file, GnpBrain.first, workers, local, progress, control)


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
        neural = run.config.neuro is not None
    if neural:
        from app.neuro_training import NetBrain

        return resume_run(path, NetBrain.rebuild, workers, local, progress, control)
    return resume_run(path, GnpBrain.rebuild, workers, local, progress, control)
