"""The brain contract: everything the lab asks of a brain family, in one base class.

A family (GNP with RL/BS/CS, an Elman net with CMA-ES, NEAT, or one registered from outside, see
`app.brains.registry`) is one subclass of `BrainFamily`, bound to a run's config. Training,
implementation, the live robots, the store's catalogue, export, the experiments and the
dashboard call these methods only; none of them asks which family it holds. Modelled on
evosax's `Strategy` (a population asked for and told its fitness) and on Gymnasium's
`register`/`make` (a family found by name).

Individuals are whatever the family chooses (a `gnp.Population`, a dict of arrays) with a
leading individual axis; the lab only passes them back to the family. What the run file stores
of them is a dict of arrays (`arrays`) of the family's `genome_layout`. Individuals that are such
dicts themselves need no code of their own (`take`, `concat`, `from_arrays`, `copies` have
defaults for them, as evosax's pytrees); `app.brains.check_family` checks a family against all
of this.
"""

from __future__ import annotations

import copy
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from pydantic import ValidationError

import gnp
import neuro
import sim
from app.loop.recording import TraceLayout
from app.settings.config import ConfigError, RunConfig
from app.settings.families import BrainSettings
from app.settings.loading import describe_problems
from app.store import RunFileError, RunReader, RunTemplate

if TYPE_CHECKING:
    from app.loop.rollout import Controllers  # the loop: imported by a family's lives


class Evolution(Protocol):
    """One run's population as generations go by: asked for individuals, told their fitness."""

    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        """(ε, α) of a generation's lives, as the file records them (NaN: no online learning)."""
        ...

    def individuals(self) -> Any:
        """The generation to live: individuals with a leading axis."""
        ...

    def arrays(self, individuals: Any) -> dict[str, np.ndarray]:
        """Individuals as the run file stores genomes."""
        ...

    def advance(self, learned: Any, fitness: np.ndarray, generation: int) -> dict[str, np.ndarray]:
        """Move on to the next generation, given this one's individuals after their lives and
        fitness; returns the next generation as a checkpoint's arrays."""
        ...


@runtime_checkable
class SecondStage(Protocol):
    """Controllers whose method has a second stage the dashboard may switch off live (GNP's
    BS branch, CS credit; `gnp.step`)."""

    second_stage: bool


@runtime_checkable
class TerminalLearner(Protocol):
    """Controllers that end an episode a task terminates with an update of their own (GNP's
    Sarsa without a successor, `gnp.end_episode`). A task's replay calls it when the episode
    terminates, not when a time limit cuts it; the robot's episodes never terminate."""

    def end_episode(self, reward: np.ndarray, terminated: np.ndarray) -> None:
        """The update after the last step, of the controllers where `terminated` ((N,) bool),
        given each one's (N,) last reward; nothing while learning is off."""
        ...


ArrayLayout = TraceLayout
"""One individual's (or one controller step's) arrays: name -> (shape, dtype)."""


@dataclass(frozen=True)
class BrainIO:
    """What a family's brains read and emit, one step of one controller: `n_inputs` readings in
    0..`sim.IR_MAX`, `n_outputs` commands in ±`sim.MAX_COMMAND`. The robot's (`ROBOT_IO`) are
    its sensors and wheels; a Gymnasium task's are its adapter's (`app.tasks.spaces`: features
    scaled to readings, commands scaled to a Box action or, for Discrete(n), output 0 read in
    n bins). `n_actions` is that n (0: no Discrete action), for a family that can emit a
    Discrete action otherwise (GNP's `processing_output` "function": one output per action).
    """

    n_inputs: int = sim.N_SENSORS
    n_outputs: int = sim.N_WHEELS
    n_actions: int = 0

    def __post_init__(self) -> None:
        if self.n_inputs < 1 or self.n_outputs < 1 or self.n_actions < 0:
            raise ValueError(f"a brain reads ≥ 1 input and emits ≥ 1 output, got {self}")


ROBOT_IO = BrainIO()
"""The robot's: `sim.N_SENSORS` IR readings in, `sim.N_WHEELS` wheel commands out."""


def checked_arrays(layout: ArrayLayout, arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """`arrays` if they are individuals of `layout`: its names, its shapes after one leading
    axis shared by all, its dtypes.

    Raises:
        RunFileError: one line naming the first mismatch.
    """
    if sorted(arrays) != sorted(layout):
        raise RunFileError(f"genome arrays must be {sorted(layout)}, got {sorted(arrays)}")
    n = len(next(iter(arrays.values()), ()))
    for name, (shape, dtype) in layout.items():
        a = arrays[name]
        if a.shape != (n, *shape) or a.dtype != np.dtype(dtype):
            raise RunFileError(
                f"genome array {name} must be {(n, *shape)} {np.dtype(dtype)}, "
                f"got {a.shape} {a.dtype}"
            )
    return arrays


class Tracer(Protocol):
    """What a live robot keeps of its controller's traced steps, for the dashboard's panels."""

    def record(self, trace: Any) -> None:
        """Take one step's trace (of a batch of one robot)."""
        ...

    def view(self) -> dict[str, Any]:
        """The `RobotSnapshot` fields this family fills (copies): GNP's visits and nodes, a
        net's activations; nothing for a family without such a view."""
        ...


class NoTracer:
    """The tracer of a family whose steps the dashboard does not draw."""

    def record(self, trace: Any) -> None:
        pass

    def view(self) -> dict[str, Any]:
        return {}


class BrainFamily(ABC):
    """One brain family, bound to a run's config. Subclass it, set `name` and `settings_model`,
    implement the abstract methods, and `app.brains.register` it; the rest has defaults (those
    of individuals for dicts of arrays: override them for other individuals).

    Capabilities are declared, not asked by type: `learns_online` (ε/α and Sarsa matter: its
    controllers are an `app.loop.rollout.OnlineLearner`), `any_io` (it sizes its brains by
    `self.io`, so it runs on any Gymnasium task too), `graph_config` (a GNP node graph the
    views draw), `network_config` (a net the dashboard draws as a network). A family with none
    of them still trains, adapts, exports and shows.
    """

    name: ClassVar[str] = ""
    """The family's name, written here once: `register` files the class under it, and it is
    `config.brain.family` of its runs (the settings model's `family` default, checked)."""
    settings_model: ClassVar[type[BrainSettings]] = BrainSettings
    """The model of the family's `brain` config section (`family` included): a subclass of
    `BrainSettings` with the family's own settings; the checked section is `self.settings`."""
    learns_online: ClassVar[bool] = False
    """Whether lives learn online (ε, α reach its controllers); else the file records NaN for
    them."""
    any_io: ClassVar[bool] = False
    """Whether its brains take their inputs and outputs from `self.io` (any `BrainIO`: the
    robot's or a task's); a family that does not runs on the robot only."""

    def __init__(self, config: RunConfig, io: BrainIO | None = None) -> None:
        """Bind the family to `config`, its brains reading and emitting `io` (the robot's when
        None).

        Raises:
            ConfigError: the `brain` section does not fit `settings_model` (named, on one line):
                a config read before the family was registered; or an `io` other than the
                robot's for a family that is not `any_io`.
        """
        self.config = config
        self.io = ROBOT_IO if io is None else io
        if self.io != ROBOT_IO and not self.any_io:
            raise ConfigError(
                f"brain family {self.name!r} runs on the robot only: its brains do not size "
                f"themselves to {self.io.n_inputs} inputs and {self.io.n_outputs} outputs "
                "(a family that does declares any_io, docs/brains.md)"
            )
        self.settings: Any = config.brain
        if not isinstance(self.settings, self.settings_model):
            try:
                self.settings = self.settings_model.model_validate(config.brain.model_dump())
            except ValidationError as error:
                raise ConfigError(
                    f"invalid settings of brain family {self.name!r}: {describe_problems(error)}"
                ) from None

    @classmethod
    def selection(cls) -> dict[str, Any]:
        """The config layer that selects this family (`gnp-lab train --brain NAME`)."""
        return {"brain": {"family": cls.name}}

    # --- what the family is called and offers -------------------------------------------------

    @property
    def label(self) -> str:
        """A short name for one robot on show (GNP's method, `Elman`, …)."""
        return self.name

    @property
    def description(self) -> str:
        """One line for run lists: `CS fuzzy`, `cmaes: Elman net, 8 hidden`."""
        return self.name

    @property
    def file_stem(self) -> str:
        """How a new run file's default name starts (`CS-fuzzy`, `cmaes`)."""
        return self.name

    @property
    def graph_config(self) -> gnp.GnpConfig | None:
        """The GNP config whose node graph the views draw, if the family has one."""
        return None

    @property
    def network_config(self) -> neuro.NetConfig | None:
        """The net the dashboard draws as a network, if the family is one."""
        return None

    def warm_key(self) -> dict[str, Any]:
        """What of the config decides which compiled code its lives need (the experiments
        warm each distinct key once per worker)."""
        return {"brain": self.name}

    # --- evolution ----------------------------------------------------------------------------

    @property
    @abstractmethod
    def genome_layout(self) -> ArrayLayout:
        """What the run file stores of one individual (`Evolution.arrays` without the
        leading axis)."""

    def run_template(self) -> RunTemplate:
        """The run file's shapes: one individual's arrays, one step's trace of one controller."""

        def zeros(layout: ArrayLayout) -> dict[str, np.ndarray]:
            return {name: np.zeros((1, *shape), dtype) for name, (shape, dtype) in layout.items()}

        return RunTemplate(self.config, zeros(self.genome_layout), zeros(self.trace_layout))

    @abstractmethod
    def first(self) -> Evolution:
        """Generation 0, drawn from the config's seed."""

    @abstractmethod
    def rebuild(
        self, generation: int, arrays: dict[str, np.ndarray], fitness: np.ndarray
    ) -> Evolution:
        """The population at a checkpoint: `arrays` of generation `generation`, `fitness` of
        the generations before it. Raises `app.store.RunFileError` when it cannot be rebuilt."""

    # --- individuals --------------------------------------------------------------------------

    def size(self, individuals: Any) -> int:
        """How many individuals `individuals` holds (the leading axis)."""
        return len(next(iter(individuals.values())))

    def take(self, individuals: Any, rows: np.ndarray | list[int]) -> Any:
        """The individuals at `rows` (copies)."""
        index = np.asarray(rows, dtype=np.int64)
        return {name: np.ascontiguousarray(a[index]) for name, a in individuals.items()}

    def concat(self, parts: list[Any]) -> Any:
        """Individuals one after the other."""
        return {name: np.concatenate([part[name] for part in parts]) for name in parts[0]}

    def from_arrays(self, arrays: dict[str, np.ndarray]) -> Any:
        """Individuals from what the run file stores (`arrays` of `genome_layout`).

        Raises:
            RunFileError: arrays not of the layout (one line, see `checked_arrays`).
        """
        return checked_arrays(self.genome_layout, arrays)

    def best(self, run: RunReader, generation: int = -1) -> Any:
        """A generation's best of `run` (one individual; negative generations from the end),
        with what it learned in its life."""
        return self.from_arrays(run.best_genome_arrays(generation))

    def for_life(self, individuals: Any) -> Any:
        """The individuals a generation's lives may change: a copy if the family learns
        online (the population evolves from what it learned), else `individuals` themselves."""
        return copy.deepcopy(individuals) if self.learns_online else individuals

    def copies(self, individual: Any, n: int) -> Any:
        """`n` copies of one individual (each learns apart)."""
        return self.take(individual, np.zeros(n, np.int64))

    # --- lives --------------------------------------------------------------------------------

    @abstractmethod
    def controllers(self, individuals: Any, engine_seeds: np.ndarray) -> Controllers:
        """Controllers driving `individuals`, one per robot; those that learn online change
        `individuals` in place. `engine_seeds` (N,) seed each controller's own stream."""

    @property
    @abstractmethod
    def trace_layout(self) -> TraceLayout:
        """What `app.loop.recording.TrajectoryRecorder` records of one controller's step."""

    def tracer(self) -> Tracer:
        """A fresh tracer of one live robot (see `Tracer`)."""
        return NoTracer()

    # --- export -------------------------------------------------------------------------------

    def export_settings(self) -> dict[str, Any]:
        """What a controller file's `settings` say of the family (GNP: method and judgment)."""
        return {"brain": self.name}

    @abstractmethod
    def controller_document(self, individual: Any, settings: dict[str, Any]) -> dict[str, Any]:
        """One individual as a controller file's JSON document (`app.store.controller_file`'s
        envelope: format, version, settings, the family's body). `settings`: what the lab ran
        it with (run, generation, seed, control period, fitness, ε/α …)."""
