"""NEAT with neat-python 2.x, its random draws isolated, its genomes run as dense batched nets.

neat-python draws from Python's global `random` module (functions bound to its hidden shared
instance). `NeatSearch` owns a `random.Random` state of its own and swaps it into the module for
the duration of each neat-python call, then swaps the caller's state back, so NEAT neither
disturbs nor depends on anyone else's draws. The search is single-threaded (the swap is not
thread-safe). Its state — genomes, species, innovation numbers, stagnation records, that
random state — is a function of (seed, parameters, the fitness of every generation told so far):
`replay` rebuilds it from those plain arrays, so a run resumes without neat-python's pickled
checkpoints (`neat.Checkpointer`).

neat-python reads its parameters from an INI file; `ini_text` writes it from `NeatParams` and
the net's sizes (`RecurrentConfig`: the robot's 8 inputs and 2 outputs unless told otherwise).
"""

from __future__ import annotations

import contextlib
import os
import random
import tempfile
from collections.abc import Iterator
from typing import Any

import neat
import numpy as np
from neat.graphs import required_for_output

from neuro.neat_params import NeatParams as NeatParams  # still importable from here
from neuro.net_configs import N_INPUTS, N_OUTPUTS, NeuroError, RecurrentConfig
from neuro.nets import zeros


def ini_text(params: NeatParams, pop_size: int, net: RecurrentConfig) -> str:
    """neat-python's INI config: a recurrent net of `net`'s inputs and tanh outputs, sum
    aggregation, fully connected inputs → outputs at the start, no hidden nodes, response fixed
    at 1."""
    p = params
    return f"""[NEAT]
fitness_criterion = max
fitness_threshold = 1e300
no_fitness_termination = True
pop_size = {pop_size}
reset_on_extinction = True

[DefaultGenome]
num_inputs = {net.n_inputs}
num_outputs = {net.n_outputs}
num_hidden = 0
feed_forward = False
initial_connection = full_direct
compatibility_disjoint_coefficient = 1.0
compatibility_weight_coefficient = 0.5
conn_add_prob = {p.conn_add_prob!r}
conn_delete_prob = {p.conn_delete_prob!r}
node_add_prob = {p.node_add_prob!r}
node_delete_prob = {p.node_delete_prob!r}
single_structural_mutation = False
structural_mutation_surer = default
activation_default = tanh
activation_options = tanh
activation_mutate_rate = 0.0
aggregation_default = sum
aggregation_options = sum
aggregation_mutate_rate = 0.0
bias_init_mean = 0.0
bias_init_stdev = 1.0
bias_init_type = gaussian
bias_max_value = 30.0
bias_min_value = -30.0
bias_mutate_power = {p.weight_mutate_power!r}
bias_mutate_rate = 0.7
bias_replace_rate = 0.1
response_init_mean = 1.0
response_init_stdev = 0.0
response_init_type = gaussian
response_max_value = 30.0
response_min_value = -30.0
response_mutate_power = 0.0
response_mutate_rate = 0.0
response_replace_rate = 0.0
weight_init_mean = 0.0
weight_init_stdev = 1.0
weight_init_type = gaussian
weight_max_value = 30.0
weight_min_value = -30.0
weight_mutate_power = {p.weight_mutate_power!r}
weight_mutate_rate = {p.weight_mutate_rate!r}
weight_replace_rate = 0.1
enabled_default = True
enabled_mutate_rate = 0.01

[DefaultSpeciesSet]
compatibility_threshold = {p.compatibility_threshold!r}

[DefaultStagnation]
species_fitness_func = max
max_stagnation = {p.max_stagnation}
species_elitism = {p.species_elitism}

[DefaultReproduction]
elitism = {p.elitism}
survival_threshold = {p.survival_threshold!r}
min_species_size = 2
"""


def neat_config(params: NeatParams, pop_size: int, net: RecurrentConfig) -> neat.Config:
    """neat-python's `Config`, read from `ini_text`'s INI (neat-python reads files only)."""
    fd, name = tempfile.mkstemp(suffix=".ini", prefix="gnp-lab-neat-")
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(ini_text(params, pop_size, net))
        return neat.Config(
            neat.DefaultGenome,
            neat.DefaultReproduction,
            neat.DefaultSpeciesSet,
            neat.DefaultStagnation,
            name,
        )
    finally:
        os.unlink(name)


def encode(genome: Any, genome_config: Any, net: RecurrentConfig) -> dict[str, np.ndarray]:
    """One genome as the dense arrays of `net` (leading axis 1).

    Units 0 … n_outputs − 1 are the output nodes; then the hidden nodes with an enabled path to
    an output, in key order. A node without enabled inputs is inactive (neat-python leaves it at
    0), and nodes with no path to an output are left out (they cannot change the outputs).

    Raises:
        NeuroError: the genome uses more than `net.max_hidden` hidden nodes, or its inputs
            and outputs are not `net`'s.
    """
    outputs = list(genome_config.output_keys)
    n_in, max_hidden = len(genome_config.input_keys), net.max_hidden
    if (n_in, len(outputs)) != (net.n_inputs, net.n_outputs):
        raise NeuroError(
            f"a NEAT genome of {n_in} inputs and {len(outputs)} outputs is not a net of "
            f"{net.n_inputs} and {net.n_outputs}"
        )
    enabled = [cg.key for cg in genome.connections.values() if cg.enabled]
    required = required_for_output(genome_config.input_keys, outputs, enabled)
    hidden = sorted(k for k in required if k not in outputs)
    if len(hidden) > max_hidden:
        raise NeuroError(
            f"a NEAT genome uses {len(hidden)} hidden nodes, more than max_hidden = {max_hidden}"
        )
    unit = {key: j for j, key in enumerate([*outputs, *hidden])}
    arrays = zeros(net, 1)
    for cg in genome.connections.values():
        i, o = cg.key
        if not cg.enabled or o not in unit:
            continue
        column = -i - 1 if i < 0 else n_in + unit[i]
        arrays["weights"][0, unit[o], column] = cg.weight
        arrays["active"][0, unit[o]] = 1
    for key, j in unit.items():
        node = genome.nodes[key]
        arrays["bias"][0, j] = node.bias
        arrays["response"][0, j] = node.response
    return arrays


class NeatSearch:
    """A neat-python `Population`, told one generation's fitness at a time.

    Args:
        params: the NEAT settings.
        pop_size: genomes per generation.
        seed: seed of the search's own `random.Random` state.
        n_inputs, n_outputs: the task's inputs and outputs (the robot's by default); the genomes
            are run as `self.net`, `params.net_config(n_inputs, n_outputs)`.
    """

    def __init__(
        self,
        params: NeatParams,
        pop_size: int,
        seed: int,
        n_inputs: int = N_INPUTS,
        n_outputs: int = N_OUTPUTS,
    ) -> None:
        self.net = params.net_config(n_inputs, n_outputs)
        self.params = params
        self.config = neat_config(params, pop_size, self.net)
        self._random = random.Random(seed)
        with self._draws():
            self.population = neat.Population(self.config)

    @contextlib.contextmanager
    def _draws(self) -> Iterator[None]:
        """Python's `random` module drawing from this search's state, for the block."""
        outer = random.getstate()
        random.setstate(self._random.getstate())
        try:
            yield
        finally:
            self._random.setstate(random.getstate())
            random.setstate(outer)

    @property
    def generation(self) -> int:
        """Generations told so far."""
        return int(self.population.generation)

    def random_state(self) -> tuple[Any, ...]:
        """The search's `random` state (`random.Random.getstate`)."""
        return self._random.getstate()

    def genomes(self) -> list[tuple[int, Any]]:
        """(key, genome) of the generation to evaluate, in the order fitness is told."""
        return list(self.population.population.items())

    def arrays(self) -> dict[str, np.ndarray]:
        """The generation to evaluate as dense nets (leading axis pop_size)."""
        genome_config = self.config.genome_config
        parts = [encode(g, genome_config, self.net) for _, g in self.genomes()]
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}

    def tell(self, fitness: np.ndarray) -> None:
        """Fitness (pop_size,) of `genomes()`, in order; then NEAT makes the next generation."""
        genomes = self.genomes()
        fitness = np.asarray(fitness, dtype=np.float64)
        if fitness.shape != (len(genomes),) or not np.all(np.isfinite(fitness)):
            raise NeuroError(
                f"fitness must be ({len(genomes)},) finite values, got {fitness.shape}"
            )

        def assign(pairs: list[tuple[int, Any]], _config: Any) -> None:
            for (_, genome), value in zip(pairs, fitness.tolist(), strict=True):
                genome.fitness = value

        with self._draws():
            self.population.run(assign, 1)
        if len(self.population.population) != len(genomes):
            raise NeuroError(
                f"NEAT made {len(self.population.population)} genomes, not {len(genomes)}"
            )


def replay(
    params: NeatParams,
    pop_size: int,
    seed: int,
    fitness: np.ndarray,
    n_inputs: int = N_INPUTS,
    n_outputs: int = N_OUTPUTS,
) -> NeatSearch:
    """The search after telling each row of `fitness` (g, pop_size) in turn, evaluating nothing
    (the sizes as `NeatSearch`'s)."""
    search = NeatSearch(params, pop_size, seed, n_inputs, n_outputs)
    for row in np.asarray(fitness, dtype=np.float64):
        search.tell(row)
    return search
