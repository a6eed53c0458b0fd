"""GNP, the thesis's brain (GNP-RL, Fuzzy GNP-RL, Fuzzy GNP-TSRL BS and CS), behind the contract.

Generation 0 is drawn from (seed, init); lives learn online by Sarsa with ε and α fixed or
scheduled (Eq. 4.1-4.2); evolution draws from (seed, generation). The run file stores the
population's arrays (`gnp.population_to_arrays`), Q tables included.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any, override

import numpy as np

import gnp
from app.brains.contract import ROBOT_IO, ArrayLayout, BrainFamily, BrainIO
from app.brains.gnp_file import GnpController
from app.brains.gnp_settings import ControllerSettings, GnpSettings, gnp_settings
from app.brains.learning import schedules
from app.loop.recording import TraceLayout
from app.loop.seeds import evolution_rng, init_rng
from app.settings.config import ConfigError, RunConfig, TrainingSettings
from app.settings.families import DEFAULT_BRAIN
from app.store import RunFileError, RunReader

if TYPE_CHECKING:
    from app.brains.gnp_controllers import GnpControllers


def initial_population(config: RunConfig, cfg: gnp.GnpConfig | None = None) -> gnp.Population:
    """Generation 0 of `cfg` (default: the robot's of `config`), drawn from (seed, init)."""
    return gnp.init_population(
        gnp_settings(config).controller.gnp_config() if cfg is None else cfg,
        config.training.population,
        init_rng(config.seed),
    )


def sized_gnp_config(controller: ControllerSettings, io: BrainIO) -> gnp.GnpConfig:
    """The GNP config of `controller` for brains of `io`: the robot's as the settings give it;
    else `io`'s inputs and outputs, and with `processing_output` "function" a Discrete(n)
    action's n outputs, one processing function per action (output 0 read in n bins: the
    function is the action).

    Raises:
        ConfigError: `processing_output` "function" on a task whose action is not Discrete.
    """
    base = controller.gnp_config()
    if io == ROBOT_IO:
        return base
    outputs = io.n_outputs
    if controller.processing_output == "function":
        if not io.n_actions:
            raise ConfigError(
                "processing_output = 'function' needs a Discrete action; a Box action takes "
                "the processing node's parameter ('parameter')"
            )
        outputs = io.n_actions
    return gnp.GnpConfig(**{**base.model_dump(), "n_inputs": io.n_inputs, "n_outputs": outputs})


def gnp_trace(cfg: gnp.GnpConfig) -> TraceLayout:
    """The layout of a GNP step's trace (`gnp.StepTrace`'s fields)."""
    return {field: (shape, gnp.TRACE_DTYPE) for field, shape in gnp.trace_shapes(cfg).items()}


def generation_epsilon_alpha(training: TrainingSettings, generation: int) -> tuple[float, float]:
    """(ε, α) of a generation: fixed, or Eq. 4.1-4.2."""
    eps_schedule, alpha_schedule = schedules(training)
    return gnp.epsilon_alpha_over_generations(
        eps_schedule, alpha_schedule, generation, training.generations, training.schedule_progress
    )


class GnpEvolution:
    """A GNP population as generations go by: evolved from its learned self each generation by
    `gnp.evolve` with the Generator of (seed, generation); ε and α of a generation from `rates`.
    The robot's runs and the Gymnasium tasks' (`app.tasks`) both evolve this way."""

    def __init__(
        self,
        cfg: gnp.GnpConfig,
        pop: gnp.Population,
        *,
        seed: int,
        generations: int,
        evolution: gnp.EvolutionConfig,
        rates: Callable[[int], tuple[float, float]],
    ) -> None:
        self._cfg, self._pop = cfg, pop
        self._seed, self._generations = seed, generations
        self._evolution, self._rates = evolution, rates

    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        return self._rates(generation)

    def individuals(self) -> gnp.Population:
        return self._pop

    def arrays(self, individuals: gnp.Population) -> dict[str, np.ndarray]:
        return gnp.population_to_arrays(individuals)

    def advance(
        self, learned: gnp.Population, fitness: np.ndarray, generation: int
    ) -> dict[str, np.ndarray]:
        self._pop = gnp.evolve(
            self._cfg,
            learned,
            fitness,
            generation,
            self._generations,
            evolution_rng(self._seed, generation),
            self._evolution,
        )
        return gnp.population_to_arrays(self._pop)


VISIT_CAPACITY = 256
"""Node visits a live GNP robot keeps (the graph's recent transitions)."""


class GraphTracer:
    """What a live GNP robot keeps of its steps: recent node visits, visits per node, the
    current node (the node-transition graph's live layer)."""

    def __init__(self, cfg: gnp.GnpConfig, capacity: int = VISIT_CAPACITY) -> None:
        self._visits = np.zeros((capacity, len(gnp.VISIT_FIELDS)), np.int64)
        self._next = self._size = 0
        self._node_visits = np.zeros(cfg.n_nodes, np.int64)
        self._current_node = 0

    def record(self, trace: gnp.StepTrace) -> None:
        count = int(trace.count[0])
        columns = [getattr(trace, f) for f in gnp.VISIT_FIELDS]
        capacity = len(self._visits)
        for k in range(count):
            self._visits[self._next] = [int(column[0, k]) for column in columns]
            self._next = (self._next + 1) % capacity
            self._size = min(self._size + 1, capacity)
        if count:
            self._current_node = int(trace.node[0, count - 1])
            np.add.at(self._node_visits, trace.node[0, :count], 1)

    def view(self) -> dict[str, Any]:
        if self._size < len(self._visits):
            visits = self._visits[: self._size].copy()
        else:
            visits = np.concatenate([self._visits[self._next :], self._visits[: self._next]])
        return {
            "visits": visits,
            "current_node": self._current_node,
            "node_visits": self._node_visits.copy(),
        }


class GnpFamily(BrainFamily):
    """GNP with the config's method (RL, BS, CS) and judgment (crisp, fuzzy)."""

    name = DEFAULT_BRAIN
    settings_model = GnpSettings
    settings: GnpSettings
    learns_online = True
    any_io = True

    def __init__(self, config: RunConfig, io: BrainIO | None = None) -> None:
        super().__init__(config, io)
        self.cfg = sized_gnp_config(self.settings.controller, self.io)

    @classmethod
    def of(cls, cfg: gnp.GnpConfig) -> GnpFamily:
        """The family of a bare GNP config (a run's other settings at their defaults): for a
        controller file's individual, or one drawn by hand, on show.

        Raises:
            ValueError: `cfg` is not a robot controller's (its inputs or outputs differ).
        """
        controller = ControllerSettings(
            method=cfg.method,
            fuzzy=cfg.fuzzy,
            n_judgment=cfg.n_judgment,
            n_processing=cfg.n_processing,
            n_sub=cfg.n_sub,
            n_branch=cfg.n_branch,
            gamma=cfg.gamma,
        )
        family = cls(RunConfig(brain=GnpSettings(controller=controller)))
        if family.cfg != cfg:
            raise ValueError(f"not a robot's GNP config: {cfg}")
        return family

    @property
    def label(self) -> str:
        return self.cfg.method

    @property
    def description(self) -> str:
        k = self.cfg.judgment_branches  # said only where it is not the thesis's two
        ways = f", {k}-way judgment" if k != 2 else ""
        return f"{self.cfg.method} {gnp.judgment_name(self.cfg.fuzzy)}{ways}"

    @property
    def file_stem(self) -> str:
        return f"{self.cfg.method}-{gnp.judgment_name(self.cfg.fuzzy)}"

    @property
    def graph_config(self) -> gnp.GnpConfig:
        return self.cfg

    def warm_key(self) -> dict[str, Any]:
        return {"brain": self.name, "controller": self.settings.controller.model_dump(mode="json")}

    @property
    def genome_layout(self) -> ArrayLayout:
        return {
            name: (shape, gnp.field_dtype(name))
            for name, shape in gnp.field_shapes(self.cfg).items()
        }

    def evolution(self, pop: gnp.Population) -> GnpEvolution:
        """`pop` as the run's population, evolving with the run's settings."""
        config = self.config
        return GnpEvolution(
            self.cfg,
            pop,
            seed=config.seed,
            generations=config.training.generations,
            evolution=self.settings.evolution,
            rates=partial(generation_epsilon_alpha, config.training),
        )

    def first(self) -> GnpEvolution:
        return self.evolution(initial_population(self.config, self.cfg))

    @override
    def rebuild(
        self, generation: int, arrays: dict[str, np.ndarray], fitness: np.ndarray
    ) -> GnpEvolution:
        return self.evolution(self.from_arrays(arrays))  # its state is its population

    # Individuals are a `gnp.Population`, not a dict of arrays.
    def size(self, individuals: gnp.Population) -> int:
        return individuals.size

    def take(self, individuals: gnp.Population, rows: np.ndarray | list[int]) -> gnp.Population:
        return gnp.take(individuals, rows)

    def concat(self, parts: list[gnp.Population]) -> gnp.Population:
        return gnp.concat(parts)

    def for_life(self, individuals: gnp.Population) -> gnp.Population:
        return individuals.copy()

    def from_arrays(self, arrays: dict[str, np.ndarray]) -> gnp.Population:
        return gnp.population_from_arrays(self.cfg, arrays)

    def best(self, run: RunReader, generation: int = -1) -> gnp.Population:
        try:
            return self.from_arrays(run.best_genome_arrays(generation))
        except gnp.GnpError as error:
            raise RunFileError(f"{run.path.name}: an invalid genome: {error}") from None

    def controllers(self, individuals: gnp.Population, engine_seeds: np.ndarray) -> GnpControllers:
        from app.brains.gnp_controllers import GnpControllers  # the loop: not for a run list

        return GnpControllers(self.cfg, individuals, engine_seeds)

    @property
    def trace_layout(self) -> TraceLayout:
        return gnp_trace(self.cfg)

    def tracer(self) -> GraphTracer:
        return GraphTracer(self.cfg)

    def export_settings(self) -> dict[str, Any]:
        return {"method": self.cfg.method, "fuzzy": self.cfg.fuzzy}

    def controller_document(
        self, individual: gnp.Population, settings: dict[str, Any]
    ) -> dict[str, Any]:
        return GnpController(self.cfg, individual, settings).document()
