"""Neural nets behind the contract: an Elman net evolved by CMA-ES (pycma), or NEAT (neat-python).

The nets see IR readings scaled to [0, 1] (÷ `sim.IR_MAX`) and their outputs in [−1, 1] become
wheel commands (× `sim.MAX_COMMAND`). They do not learn online: the file records ε and α as
NaN. A step's trace is the nets' activations (what the dashboard draws); a new episode zeroes
them.

The lab is the GNP arm's: the same lives, fitness (Eq. 2.8), arena, life time and budget in
robot-steps, the optimiser's population being `training.population`. The optimiser draws from a
stream of its own (`app.loop.seeds.optimiser_seed`); its state is a function of that seed and of
the fitness table the file holds, so a resume rebuilds it by replaying the told fitness (no
pickles) and checks it against the checkpointed population, bit for bit.
"""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import dataclass
from typing import Any, Protocol, override

import numpy as np

import neuro
import sim
from app.brains.contract import ArrayLayout, BrainFamily, BrainIO, Evolution
from app.brains.net_file import NetController
from app.brains.net_settings import NetSettings
from app.loop.recording import TraceLayout
from app.loop.seeds import optimiser_seed
from app.settings.config import RunConfig
from app.store import RunFileError
from neuro.neat_params import NeatParams


@dataclass(frozen=True)
class NeuralTrace:
    """What N nets did in one step."""

    activation: np.ndarray  # (N, units) each net's units after the step (Elman: context)


def trace_layout(net: neuro.NetConfig) -> TraceLayout:
    """The recorded trace of one net: its units' activations per step."""
    return {"activation": ((net.n_units,), np.dtype(np.float64))}


class NeuralControllers:
    """N neural controllers, one per robot (satisfies `app.loop.rollout.Controllers`)."""

    def __init__(self, net: neuro.NetConfig, arrays: dict[str, np.ndarray]) -> None:
        self.net = net
        self.arrays = arrays
        self.state = neuro.init_state(net, neuro.check_arrays(net, arrays))

    @property
    def size(self) -> int:
        return len(self.state)

    def act(
        self, observations: np.ndarray, reward: np.ndarray, *, trace: bool
    ) -> tuple[np.ndarray, NeuralTrace | None]:
        del reward  # a net reads no reward
        outputs = neuro.step(self.net, self.arrays, self.state, observations / sim.IR_MAX)
        commands = outputs * sim.MAX_COMMAND
        return commands, NeuralTrace(self.state.copy()) if trace else None

    def reset_episode(self) -> None:
        self.state[...] = 0.0


class NetworkTracer:
    """What a live net keeps of its steps: its units after the last step and before it (what
    its recurrent weights read)."""

    def __init__(self, net: neuro.NetConfig) -> None:
        self._activation = np.zeros(net.n_units)
        self._context = np.zeros(net.n_units)

    def record(self, trace: NeuralTrace) -> None:
        self._context, self._activation = self._activation, trace.activation[0].copy()

    def view(self) -> dict[str, Any]:
        return {"activation": self._activation.copy(), "context": self._context.copy()}


# --- the optimisers ---------------------------------------------------------------------------


class Optimiser(Protocol):
    def arrays(self) -> dict[str, np.ndarray]:
        """The generation to evaluate: nets with a leading population axis."""
        ...

    def tell(self, fitness: np.ndarray) -> None:
        """Its fitness; the optimiser moves on to the next generation."""
        ...


class _CmaesOptimiser:
    def __init__(self, net: neuro.ElmanConfig, sigma0: float, population: int, seed: int) -> None:
        from neuro.cmaes import Cmaes  # pycma: imported when a run evolves, not when it is listed

        self.net = net
        self.es = Cmaes(self.net.n_params, sigma0, population, optimiser_seed(seed))

    def arrays(self) -> dict[str, np.ndarray]:
        return neuro.from_flat(self.net, self.es.ask())

    def tell(self, fitness: np.ndarray) -> None:
        self.es.tell(fitness)


class NetEvolution(Evolution):
    """Nets as generations go by: an optimiser asked for each generation and told its fitness."""

    def __init__(self, optimiser: Optimiser) -> None:
        self._optimiser = optimiser
        self._arrays = optimiser.arrays()

    @override
    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        return float("nan"), float("nan")  # no online learning

    def individuals(self) -> dict[str, np.ndarray]:
        return self._arrays

    def arrays(self, individuals: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return individuals

    @override
    def advance(
        self, learned: dict[str, np.ndarray], fitness: np.ndarray, generation: int
    ) -> dict[str, np.ndarray]:
        self._optimiser.tell(fitness)
        self._arrays = self._optimiser.arrays()
        return self._arrays


# --- the families -----------------------------------------------------------------------------


class NetFamily(BrainFamily):
    """A net of the config's `brain` section (`NetSettings`), evolved by its optimiser."""

    settings_model = NetSettings
    settings: NetSettings
    any_io = True

    def __init__(self, config: RunConfig, io: BrainIO | None = None) -> None:
        super().__init__(config, io)
        if self.settings.family != self.name:
            raise ValueError(f"a {self.name} family needs a brain section of that family")
        self.net = self.net_config()

    @staticmethod
    def of(net: neuro.NetConfig) -> NetFamily:
        """The family of a bare net (a run's other settings at their defaults): for a
        controller file's net, or one built by hand, on show; its inputs and outputs the
        net's (a task's net's too)."""
        io = BrainIO(net.n_inputs, net.n_outputs)
        if isinstance(net, neuro.ElmanConfig):
            settings = NetSettings(family="cmaes", hidden=net.hidden)
            family: NetFamily = CmaesFamily(RunConfig(brain=settings), io)
        else:
            neat = NeatParams(max_hidden=net.max_hidden)
            family = NeatFamily(RunConfig(brain=NetSettings(family="neat", neat=neat)), io)
        assert family.net == net
        return family

    @property
    def network_config(self) -> neuro.NetConfig:
        return self.net

    def warm_key(self) -> dict[str, Any]:
        return {"brain": self.name, "neuro": self.settings.model_dump(mode="json")}

    @abstractmethod
    def net_config(self) -> neuro.NetConfig:
        """The nets this family evolves, from its settings."""

    @abstractmethod
    def make_optimiser(self) -> Optimiser:
        """A new optimiser at generation 0."""

    @property
    def genome_layout(self) -> ArrayLayout:
        return {name: (shape, neuro.field_dtype(name)) for name, shape in self.net.shapes().items()}

    def first(self) -> NetEvolution:
        return NetEvolution(self.make_optimiser())

    @override
    def rebuild(
        self, generation: int, arrays: dict[str, np.ndarray], fitness: np.ndarray
    ) -> NetEvolution:
        """The optimiser rebuilt by telling it each row of `fitness`, checked against the
        checkpoint.

        Raises:
            RunFileError: the replay does not give the checkpointed population (e.g. another
                pycma or neat-python version than the run's).
        """
        optimiser = self.make_optimiser()
        for row in fitness:
            optimiser.arrays()
            optimiser.tell(row)
        evolution = NetEvolution(optimiser)
        rebuilt = evolution.individuals()
        if sorted(rebuilt) != sorted(arrays) or not all(
            np.array_equal(rebuilt[k], arrays[k]) for k in rebuilt
        ):
            raise RunFileError(
                "replaying the optimiser does not give the checkpointed population "
                "(another pycma or neat-python version?); it cannot be resumed"
            )
        return evolution

    @override
    def controllers(
        self, individuals: dict[str, np.ndarray], engine_seeds: np.ndarray
    ) -> NeuralControllers:
        return NeuralControllers(self.net, individuals)

    @property
    def trace_layout(self) -> TraceLayout:
        return trace_layout(self.net)

    def tracer(self) -> NetworkTracer:
        return NetworkTracer(self.net)

    def controller_document(
        self, individual: dict[str, np.ndarray], settings: dict[str, Any]
    ) -> dict[str, Any]:
        return NetController(self.net, individual, settings).document()


class CmaesFamily(NetFamily):
    """An Elman net whose weights CMA-ES evolves."""

    name = "cmaes"

    def net_config(self) -> neuro.ElmanConfig:
        io = self.io
        return neuro.ElmanConfig(
            hidden=self.settings.hidden, n_inputs=io.n_inputs, n_outputs=io.n_outputs
        )

    @property
    def label(self) -> str:
        return "Elman"

    @property
    def description(self) -> str:
        return f"{self.name}: Elman net, {self.settings.hidden} hidden"

    def make_optimiser(self) -> Optimiser:
        training, sigma0 = self.config.training, self.settings.sigma0
        return _CmaesOptimiser(self.net_config(), sigma0, training.population, self.config.seed)


class NeatFamily(NetFamily):
    """A recurrent net whose topology and weights NEAT evolves."""

    name = "neat"

    def net_config(self) -> neuro.NetConfig:
        return self.settings.neat.net_config(self.io.n_inputs, self.io.n_outputs)

    @property
    def label(self) -> str:
        return "NEAT"

    @property
    def description(self) -> str:
        return f"{self.name}: NEAT net, ≤ {self.settings.neat.max_hidden} hidden nodes"

    def make_optimiser(self) -> Optimiser:
        from neuro.neat_evolution import NeatSearch  # neat-python: imported when a run evolves

        population, seed = self.config.training.population, optimiser_seed(self.config.seed)
        io = self.io
        return NeatSearch(self.settings.neat, population, seed, io.n_inputs, io.n_outputs)
