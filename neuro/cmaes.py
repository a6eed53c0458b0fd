"""CMA-ES on a net's flat weights, with pycma, drawing from a seeded stream of its own.

pycma draws its Gaussian samples through its `randn` option; we give it a `numpy.random.Generator`
of its own and switch its seeding off (`seed=nan`), so it neither reads nor seeds NumPy's global
RNG. Its state is then a function of (seed, settings, the fitness of every generation told so
far): `replay` rebuilds it from those plain arrays, which is how a run resumes without pickles.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import cma
import numpy as np

from neuro.nets import NeuroError


class Cmaes:
    """pycma's `CMAEvolutionStrategy` maximising fitness, asked and told one generation at a time.

    Args:
        n: dimension (the net's `n_params`).
        sigma0: initial step size; the search starts at the zero vector.
        popsize: candidates per generation λ.
        seed: entropy of the sampling stream (an int or a list of ints, as `SeedSequence`).
    """

    def __init__(self, n: int, sigma0: float, popsize: int, seed: int | list[int]) -> None:
        if n < 1 or popsize < 2 or not sigma0 > 0:
            raise NeuroError(
                f"CMA-ES needs n ≥ 1, popsize ≥ 2, σ0 > 0 (got {n}, {popsize}, {sigma0})"
            )
        self._rng = np.random.default_rng(np.random.SeedSequence(seed))
        options: dict[str, Any] = {
            "popsize": popsize,
            "seed": math.nan,  # never seed (or read) NumPy's global RNG
            "randn": self._randn,
            "verbose": -9,
            "verb_log": 0,
            "verb_disp": 0,
        }
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # pycma's notes on option values go nowhere useful
            self.es = cma.CMAEvolutionStrategy(np.zeros(n), sigma0, options)
        self._asked: np.ndarray | None = None

    def _randn(self, *shape: int) -> np.ndarray:
        return self._rng.standard_normal(shape)

    @property
    def generation(self) -> int:
        """Generations told so far."""
        return int(self.es.countiter)

    def ask(self) -> np.ndarray:
        """(popsize, n) candidates of the next generation (asking again gives the same ones)."""
        if self._asked is None:
            self._asked = np.array(self.es.ask(), dtype=np.float64)
        return self._asked.copy()

    def tell(self, fitness: np.ndarray) -> None:
        """Fitness (popsize,) of the asked candidates, higher is better."""
        asked = self.ask()
        fitness = np.asarray(fitness, dtype=np.float64)
        if fitness.shape != (len(asked),) or not np.all(np.isfinite(fitness)):
            raise NeuroError(f"fitness must be ({len(asked)},) finite values, got {fitness.shape}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.es.tell(list(asked), (-fitness).tolist())  # pycma minimises
        self._asked = None

    def summary(self) -> dict[str, Any]:
        """The search distribution's centre and step size, as plain values."""
        return {
            "generation": self.generation,
            "mean": np.asarray(self.es.mean, dtype=np.float64).copy(),
            "sigma": float(self.es.sigma),
        }


def replay(
    n: int, sigma0: float, popsize: int, seed: int | list[int], fitness: np.ndarray
) -> Cmaes:
    """The optimiser after telling each row of `fitness` (g, popsize) in turn: the state of a
    run that evaluated g generations, rebuilt without evaluating anything."""
    es = Cmaes(n, sigma0, popsize, seed)
    for row in np.asarray(fitness, dtype=np.float64):
        es.ask()
        es.tell(row)
    return es
