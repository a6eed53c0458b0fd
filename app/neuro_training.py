"""Training a neural brain (CMA-ES on an Elman net, or NEAT) into the same run files as GNP.

The lab is the GNP arm's: the same lives (`app.seeds.life_seeds`: start poses, noise streams),
fitness (Eq. 2.8, mean reward per step), arena, life time and budget in robot-steps (population ×
generations × steps, the optimiser's population being `training.population`). The optimiser
draws from a stream of its own (`app.seeds.optimiser_seed`); its state is a function of that
seed and of the fitness table the file holds, so a resume rebuilds it by replaying the told
fitness (no pickles) and checks it against the checkpointed population, bit for bit.
Individual i always lives at the same place of the same world (`app.lives.shards`), so
results do not depend on the number of workers. The loop is `app.generations`, GNP's own; this
module holds the nets' brain (`NetBrain`) and their run file's shapes.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

import neuro
from app.config import RunConfig
from app.neural import trace_layout
from app.seeds import optimiser_seed
from app.store import RunFileError, RunTemplate
from neuro.cmaes import Cmaes
from neuro.neat_evolution import NeatSearch


class Optimiser(Protocol):
    def arrays(self) -> dict[str, np.ndarray]:
        """The generation to evaluate: nets with a leading population axis."""
        ...

    def tell(self, fitness: np.ndarray) -> None:
        """Its fitness; the optimiser moves on to the next generation."""
        ...


class _CmaesOptimiser:
    def __init__(self, config: RunConfig) -> None:
        assert config.neuro is not None
        self.net = neuro.ElmanConfig(hidden=config.neuro.hidden)
        self.es = Cmaes(
            self.net.n_params,
            config.neuro.sigma0,
            config.training.population,
            optimiser_seed(config.seed),
        )

    def arrays(self) -> dict[str, np.ndarray]:
        return neuro.from_flat(self.net, self.es.ask())

    def tell(self, fitness: np.ndarray) -> None:
        self.es.tell(fitness)


def make_optimiser(config: RunConfig) -> Optimiser:
    """A new optimiser for `config` (its `neuro` section set), at generation 0."""
    assert config.neuro is not None
    if config.neuro.optimiser == "cmaes":
        return _CmaesOptimiser(config)
    return NeatSearch(config.neuro.neat, config.training.population, optimiser_seed(config.seed))


def replay_optimiser(config: RunConfig, fitness: np.ndarray) -> Optimiser:
    """The optimiser after telling each row of `fitness` (g, population): a run's state after g
    generations, rebuilt without living anything."""
    optimiser = make_optimiser(config)
    for row in fitness:
        optimiser.arrays()
        optimiser.tell(row)
    return optimiser


class NetBrain:
    """Nets for `app.generations`: an optimiser asked for each generation and told its fitness.
    Nets do not learn online: the file records ε and α as NaN."""

    def __init__(self, optimiser: Optimiser) -> None:
        self._optimiser = optimiser
        self._arrays = optimiser.arrays()

    @classmethod
    def first(cls, config: RunConfig) -> NetBrain:
        return cls(make_optimiser(config))

    @classmethod
    def rebuild(
        cls, config: RunConfig, generation: int, arrays: dict[str, np.ndarray], fitness: np.ndarray
    ) -> NetBrain:
        """The optimiser rebuilt from the told fitness, checked against the checkpoint.

        Raises:
            RunFileError: the replay does not give the checkpointed population (e.g. another
                pycma or neat-python version than the run's).
        """
        brain = cls(replay_optimiser(config, fitness))
        rebuilt = brain._arrays
        if sorted(rebuilt) != sorted(arrays) or not all(
            np.array_equal(rebuilt[k], arrays[k]) for k in rebuilt
        ):
            raise RunFileError(
                "replaying the optimiser does not give the checkpointed population "
                "(another pycma or neat-python version?); it cannot be resumed"
            )
        return brain

    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        return float("nan"), float("nan")  # no online learning

    def individuals(self) -> dict[str, np.ndarray]:
        return self._arrays

    def arrays(self, individuals: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return individuals

    def advance(
        self, learned: dict[str, np.ndarray], fitness: np.ndarray, generation: int
    ) -> dict[str, np.ndarray]:
        self._optimiser.tell(fitness)
        self._arrays = self._optimiser.arrays()
        return self._arrays


def neural_template(config: RunConfig) -> RunTemplate:
    """The run file's shapes: one net's arrays, one step's activations of one net."""
    assert config.neuro is not None
    net = config.neuro.net_config()
    trace = {
        name: np.zeros((1, *shape), dtype) for name, (shape, dtype) in trace_layout(net).items()
    }
    return RunTemplate(config=config, genome=neuro.zeros(net, 1), trace=trace)
