"""Settings of a run on a Gymnasium task: the task, the brain family's settings, the training.

A `TaskRunConfig` names its brain as a robot run's config does: a `brain` section holding any
registered family's own settings (GNP's `GnpSettings`: `controller`, `evolution`; a net's
`NetSettings`; a family registered from outside), checked with the family's model as a robot
run's is, and, of the training phase, what a task uses: population, generations, a life's cap
in steps and the ε/α schedules (built from the lab's `TrainingSettings`, so `gnp-lab train`'s
options set them). `family` binds the brain family to the task: to a `RunConfig` of the run's
seed, brain and training sizes, its brains reading the task's features and emitting its
actions (`BrainIO` of the task's adapter). A task config stored in layout 1
(`controller`, `evolution` at the top; every task run and preset before issue #46) is moved to
layout 2 when read (`app.settings.layouts.layout_2`); `task_layout_1` maps a dumped one back,
for a task experiment's identity (`app.experiments.ledger`).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cached_property
from typing import Any

import gymnasium as gym
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializeAsAny,
    field_validator,
    model_validator,
)

import gnp
from app.brains.contract import BrainFamily, BrainIO
from app.brains.gnp_brain import sized_gnp_config
from app.brains.gnp_settings import GnpSettings
from app.brains.learning import schedules
from app.brains.registry import family_of
from app.settings.config import ConfigError, RunConfig, TrainingSettings, brain_field
from app.settings.families import DEFAULT_BRAIN, BrainSettings, brain_section
from app.settings.layouts import GNP_SECTIONS, layout_1, layout_2
from app.store.schema import TASK_SIZES
from app.tasks.common import TEST_PROTOCOLS, EpisodeProtocol, TaskError, TestProtocol
from app.tasks.spaces import TaskAdapter, task_adapter
from gnp import Schedule
from gnp.config import GenerationProgress

Bounds = tuple[float | None, ...] | None


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class TaskSettings(_Frozen):
    """Which Gymnasium task, and the bounds GNP scales its features and actions by."""

    id: str = Field(description="a registered Gymnasium id, e.g. CartPole-v1")
    obs_low: Bounds = Field(
        default=None, description="low bound per observation feature (null = the space's)"
    )
    obs_high: Bounds = Field(default=None, description="high bound per observation feature")
    act_low: Bounds = Field(default=None, description="low bound per Box action component")
    act_high: Bounds = Field(default=None, description="high bound per Box action component")

    def adapter(self) -> TaskAdapter:
        """The task's adapter (builds one environment to read its spaces).

        Raises:
            TaskError: unknown id, or a space GNP cannot judge or emit.
        """
        env = make_env(self.id)
        try:
            return task_adapter(
                self.id,
                env.observation_space,
                env.action_space,
                self.obs_low,
                self.obs_high,
                self.act_low,
                self.act_high,
            )
        finally:
            env.close()


def make_env(task: str, render_mode: str | None = None) -> gym.Env:
    """`gymnasium.make(task)` (with `render_mode` if given: the dashboard's "rgb_array"), an
    unknown or unusable id as one TaskError line. Gymnasium's `module:id` form is refused: it
    would import any module named (code run at import), and a task is a registered id."""
    if ":" in task:
        raise TaskError(
            f"task {task!r}: give a registered Gymnasium id (e.g. CartPole-v1); the "
            "module:id form, which imports a module, is not accepted"
        )
    try:
        return gym.make(task) if render_mode is None else gym.make(task, render_mode=render_mode)
    except gym.error.DependencyNotInstalled as error:
        raise TaskError(f"task {task!r} cannot be made: {error}") from None
    except gym.error.Error as error:
        raise TaskError(f"unknown task {task!r}: {str(error).splitlines()[0]}") from None
    except (ImportError, ModuleNotFoundError) as error:  # an id whose package is missing
        raise TaskError(f"task {task!r} cannot be made: {error}") from None


class TaskTraining(EpisodeProtocol):
    """The training phase on a task: each individual lives one episode, capped at `steps`; its
    episodes' seeds and its final elite's test (`EpisodeProtocol`)."""

    population: int = Field(default=100, ge=2, le=100_000, description="individuals")
    generations: int = Field(default=20, ge=1, le=1_000_000, description="generations G")
    steps: int = Field(
        default=1000, ge=1, le=1_000_000, description="a life's cap in steps (one episode)"
    )
    epsilon: Schedule = Field(default=Schedule.fixed(0.1), description="ε over generations")
    alpha: Schedule = Field(default=Schedule.fixed(0.1), description="α over generations")
    schedule_progress: GenerationProgress = Field(
        default="last-generation-min", description="progress of Eq. 4.1-4.2"
    )

    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        """(ε, α) of a generation: fixed, or Eq. 4.1-4.2."""
        return gnp.epsilon_alpha_over_generations(
            self.epsilon, self.alpha, generation, self.generations, self.schedule_progress
        )


PROTOCOL_FIELDS = tuple(EpisodeProtocol.model_fields)
"""`EpisodeProtocol`'s settings, which `TaskTraining` holds and a `[task]` section sets."""


TASK_LAYOUT_1 = ("seed", "task", *GNP_SECTIONS, "training")
"""A task config's sections in layout 1, in the order its JSON held them."""


def task_layout_1(data: Mapping[str, Any]) -> dict[str, Any]:
    """A dumped task config (`TaskRunConfig.model_dump(mode="json")`, some fields left out or
    not) in layout 1, its sections in the order layout 1 wrote them: a task run's identity as
    every committed ledger holds it."""
    brain = data.get("brain")
    family = brain.get("family", DEFAULT_BRAIN) if isinstance(brain, Mapping) else DEFAULT_BRAIN
    out = layout_1(data, family)
    return {key: out[key] for key in TASK_LAYOUT_1 if key in out} | {
        key: value for key, value in out.items() if key not in TASK_LAYOUT_1
    }


class TaskRunConfig(_Frozen):
    """Everything a task run's results depend on."""

    seed: int = Field(default=0, ge=0, le=2**63 - 1, description="random seed of the run")
    task: TaskSettings
    brain: SerializeAsAny[BrainSettings] = brain_field()
    training: TaskTraining = TaskTraining()

    @model_validator(mode="before")
    @classmethod
    def _in_layout_2(cls, data: Any) -> Any:
        """A stored task config of layout 1 moved to layout 2."""
        return layout_2(data) if isinstance(data, Mapping) else data

    _brain_section = field_validator("brain", mode="before")(brain_section)

    @cached_property
    def adapter(self) -> TaskAdapter:
        return self.task.adapter()

    @property
    def io(self) -> BrainIO:
        """What a brain reads and emits on the task: its features, its commands (one for
        Discrete(n), read in n bins; d for Box(d)), n of a Discrete(n) action."""
        adapter = self.adapter
        return BrainIO(adapter.n_inputs, adapter.n_outputs, adapter.n_actions)

    def run_config(self) -> RunConfig:
        """The robot run's config a family is bound with: the run's seed and brain, its
        population, generations and a life's cap (the arena's settings at their defaults,
        unused; the store binds the same, `app.store.schema.task_run_header`). A generation's
        ε and α are the task's (`TaskTraining.epsilon_alpha`)."""
        sizes = TrainingSettings(**{name: getattr(self.training, name) for name in TASK_SIZES})
        return RunConfig(seed=self.seed, brain=self.brain, training=sizes)

    @property
    def family(self) -> BrainFamily:
        """The brain family bound to the task (`run_config`, `io`): bound anew at each call
        (a tenth of a millisecond), so a copy of the config with other settings
        (`model_copy`) never holds its original's family.

        Raises:
            TaskError: the family is not registered, or cannot run on this task (one line).
        """
        try:
            return family_of(self.run_config(), self.io)
        except ConfigError as error:
            raise TaskError(f"{self.task.id}: {error}") from None

    @property
    def description(self) -> str:
        """The brain family's line (`CS fuzzy`, `cmaes: Elman net, 8 hidden`), without making
        the task's env (the family described as bound to the robot's io: its words do not
        depend on it); `NAME (not registered)` for a family not registered here."""
        try:
            return family_of(self.run_config()).description
        except ConfigError:
            return f"{self.brain.family} (not registered)"

    def gnp_settings(self) -> GnpSettings:
        """The brain's settings of a GNP run.

        Raises:
            TaskError: the run's brain is of another family.
        """
        if not isinstance(self.brain, GnpSettings):
            raise TaskError(f"a GNP task run's config is needed, not one of {self.brain.family!r}")
        return self.brain

    def gnp_config(self) -> gnp.GnpConfig:
        """A GNP run's brain (`app.brains.gnp_brain.sized_gnp_config`): the lab's controller
        settings, inputs and outputs the task's; with `processing_output` "function" a
        Discrete(n) task's brain has n outputs, one processing function per action.

        Raises:
            TaskError: not a GNP run, or `processing_output` "function" on a task whose action
                is not Discrete.
        """
        try:
            return sized_gnp_config(self.gnp_settings().controller, self.io)
        except ConfigError as error:
            raise TaskError(f"{self.task.id}: {error}") from None

    @classmethod
    def from_run_config(
        cls, config: RunConfig, task: TaskSettings, protocol: EpisodeProtocol | None = None
    ) -> TaskRunConfig:
        """The task run of the lab's settings (seed, brain of any family, population,
        generations, steps, ε/α schedules) and of `protocol` (its episodes and test; the
        defaults when None); the arena, noise and physics do not apply."""
        eps, alpha = schedules(config.training)
        training = TaskTraining(
            population=config.training.population,
            generations=config.training.generations,
            steps=config.training.steps,
            epsilon=eps,
            alpha=alpha,
            schedule_progress=config.training.schedule_progress,
            **{name: getattr(protocol or EpisodeProtocol(), name) for name in PROTOCOL_FIELDS},
        )
        return cls(seed=config.seed, task=task, brain=config.brain, training=training)


__all__ = [
    "TEST_PROTOCOLS",
    "TaskError",
    "TaskRunConfig",
    "TaskSettings",
    "TaskTraining",
    "TestProtocol",
    "make_env",
    "task_layout_1",
]
