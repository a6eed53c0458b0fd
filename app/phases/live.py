"""A small live stepping loop: one to three robots, each with its own controller, stepped together.

The dashboard drives a `LiveSession` from a background thread at a steady rate and draws its
`snapshot()`; nothing here knows about viser, so the loop is unit-testable. Each robot lives in
its own `sim.World` (n = 1) because robots on show may run controllers of different methods
(e.g. BS beside CS); the world's per-robot streams make each robot's run the same as it would be
in any batch.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

import gnp
import sim
from app.brains.contract import BrainFamily, SecondStage
from app.brains.learning import LearningSettings
from app.loop.rollout import Batch
from app.settings.arenas import new_world
from app.settings.config import ImplementationSettings
from app.settings.fields import SettingError, check_field
from sim import CONTROL_PERIOD_S, FaultMode


class LiveError(ValueError):
    """A live-session request that cannot be honoured (robot count, start pose, a noise σ out
    of the settings' range); a bad sensor or fault mode is refused by the world
    (`sim.WorldError`) before anything changes."""


def checked_noise(sigma: float) -> float:
    """`sigma` as a live noise σ: within the implementation phase's `noise_sigma` field, the
    bounds the Faults tab's control shows (the world alone takes any finite σ ≥ 0).

    Raises:
        LiveError: `noise σ: problem (got sigma)`, the line the page shows.
    """
    try:
        return float(check_field(ImplementationSettings, "noise_sigma", sigma, "noise σ"))
    except SettingError as error:
        raise LiveError(str(error)) from None


class Ring:
    """A fixed-capacity ring buffer of rows; `values()` returns them oldest first (a copy)."""

    def __init__(self, capacity: int, row_shape: tuple[int, ...] = (), dtype: type = float):
        self._data: np.ndarray = np.zeros((capacity, *row_shape), dtype=dtype)
        self._next = 0
        self._size = 0

    @property
    def capacity(self) -> int:
        return self._data.shape[0]

    def __len__(self) -> int:
        return self._size

    def append(self, row: object) -> None:
        self._data[self._next] = row
        self._next = (self._next + 1) % self.capacity
        self._size = min(self._size + 1, self.capacity)

    def clear(self) -> None:
        self._next = self._size = 0

    def values(self) -> np.ndarray:
        if self._size < self.capacity:
            return self._data[: self._size].copy()
        return np.concatenate([self._data[self._next :], self._data[: self._next]])


@dataclass(frozen=True)
class RobotSnapshot:
    """What one robot on show looks like now; arrays are copies, safe to read from any thread."""

    label: str
    method: str  # the family's label: GNP's method, `Elman`, `NEAT`, …
    t: int
    pose: np.ndarray  # (3,) x mm, y mm, heading rad
    true_readings: np.ndarray  # (8,)
    seen_readings: np.ndarray  # (8,) with noise and faults: what the controller used
    broken: np.ndarray  # (8,) bool
    fault_mode: FaultMode | None
    trajectory: np.ndarray  # (P, 2) mm, oldest first
    trajectory_reward: np.ndarray  # (P,) reward of the step that ended at each point
    reward_steps: np.ndarray  # (H,) step index
    rewards: np.ndarray  # (H,) reward per step
    broken_counts: np.ndarray  # (H,) number of broken sensors at each step
    fault_steps: tuple[int, ...]  # steps at which sensors broke (within the history)
    epsilon: float
    alpha: float
    mean_reward: float  # over the reward history
    # What the family's tracer fills (`BrainFamily.tracer`); empty for a family without it.
    visits: np.ndarray = field(default_factory=lambda: np.zeros((0, len(gnp.VISIT_FIELDS)), int))
    # (V, 5) int: the `gnp.VISIT_FIELDS` of each visit; oldest first
    current_node: int = 0
    node_visits: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    # (n_nodes,) visits to each node in this life (the simplified graph hides the others)
    commands: np.ndarray = field(default_factory=lambda: np.zeros(2))  # (2,) of the last step
    learns_online: bool = True  # its family's: else ε and α mean nothing to it
    activation: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # a net's (units,) state after the last step (GNP: empty)
    context: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # a net's (units,) state before it: what its recurrent weights read (GNP: empty)


@dataclass
class LiveRobot:
    """One robot on show and its controller; `population` holds one individual of `family`
    (with a leading axis of 1)."""

    label: str
    family: BrainFamily
    population: Any
    world: sim.World
    seed: int
    trajectory_capacity: int = 600
    history_capacity: int = 1000
    _batch: Batch = field(init=False)
    _seen: np.ndarray = field(init=False)
    _fault_steps: list[int] = field(init=False, default_factory=list)
    _fault_mode: FaultMode | None = field(init=False, default=None)
    _rates: tuple[float, float] = field(init=False, default=(0.0, 0.0))

    def __post_init__(self) -> None:
        self._trajectory = Ring(self.trajectory_capacity, (2,))
        self._trajectory_reward = Ring(self.trajectory_capacity)
        self._reward_steps = Ring(self.history_capacity, (), np.int64)
        self._rewards = Ring(self.history_capacity)
        self._broken_counts = Ring(self.history_capacity, (), np.int64)
        controllers = self.family.controllers(self.population, np.array([self.seed]))
        self._batch = Batch(self.world, controllers)
        self._tracer = self.family.tracer()
        self._commands = np.zeros(2)
        self._seen = self.world.sense().copy()
        self._trajectory.append(self.world.poses[0, :2])
        self._trajectory_reward.append(0.0)

    @property
    def t(self) -> int:
        return int(self.world.t)

    def step(self, learning: LearningSettings) -> None:
        """One control step through the lab's loop (traced), then the views' histories."""
        fault_step = self._fault_steps[-1] if self._fault_steps else None
        epsilon, alpha = learning.rates(self.t, fault_step)
        self._rates = (epsilon, alpha)
        if isinstance(self._batch.controllers, SecondStage):  # GNP's live ablation
            self._batch.controllers.second_stage = learning.second_stage
        record = self._batch.step(epsilon, alpha, learn=learning.online, trace=True)
        assert record.trace is not None
        reward = float(record.reward[0])
        self._seen = record.observations
        self._commands = record.commands[0].copy()
        self._tracer.record(record.trace)
        self._trajectory.append(self.world.poses[0, :2])
        self._trajectory_reward.append(reward)
        self._reward_steps.append(self.t)
        self._rewards.append(reward)
        self._broken_counts.append(int(np.count_nonzero(self.world.broken[0])))

    def break_sensors(self, sensors: Sequence[int], mode: FaultMode) -> None:
        self.world.break_sensors(list(sensors), mode=mode)
        self._fault_steps = [*self._fault_steps[-7:], self.t]
        self._fault_mode = mode

    def repair(self) -> None:
        self.world.repair()
        self._fault_mode = None

    def snapshot(self) -> RobotSnapshot:
        steps = self._reward_steps.values()
        rewards = self._rewards.values()
        oldest = int(steps[0]) if len(steps) else self.t
        return RobotSnapshot(
            label=self.label,
            method=self.family.label,
            t=self.t,
            pose=self.world.poses[0].copy(),
            true_readings=self.world.sense()[0].copy(),
            seen_readings=self._seen[0].copy(),
            broken=np.asarray(self.world.broken[0], bool).copy(),
            fault_mode=self._fault_mode,
            trajectory=self._trajectory.values(),
            trajectory_reward=self._trajectory_reward.values(),
            reward_steps=steps,
            rewards=rewards,
            broken_counts=self._broken_counts.values(),
            fault_steps=tuple(s for s in self._fault_steps if s >= oldest),
            epsilon=self._rates[0],
            alpha=self._rates[1],
            mean_reward=float(rewards.mean()) if len(rewards) else 0.0,
            commands=self._commands.copy(),
            learns_online=self.family.learns_online,
            **self._tracer.view(),
        )


MAX_ROBOTS = 3
"""Robots one live session steps together (RL, BS and CS side by side)."""


@dataclass(frozen=True)
class RobotSpec:
    """What to put on show: a label, a brain family and one individual of it (with a leading
    axis of 1)."""

    label: str
    family: BrainFamily
    population: Any


class LiveSession:
    """One to three robots in the same arena from the same start pose, stepped together.

    All methods are thread-safe: the dashboard's loop thread calls `step`, GUI callbacks call
    the rest.

    Args:
        arena: the arena the robots live in.
        robots: one to MAX_ROBOTS robots to show.
        start: index of the start pose (0..9) in `arena.start_poses`.
        seed: seeds each robot's world and controller streams (the same for every robot).
        noise_sigma: sensor noise σ (Eq. 2.6) applied to what the controllers see (see
            `checked_noise`).
        learning: online learning settings.
        control_period: simulated seconds per control step (the run's setting).
    """

    def __init__(
        self,
        arena: sim.Arena,
        robots: Sequence[RobotSpec],
        start: int = 0,
        seed: int = 0,
        noise_sigma: float = 0.0,
        learning: LearningSettings | None = None,
        control_period: float = CONTROL_PERIOD_S,
    ) -> None:
        if not 1 <= len(robots) <= MAX_ROBOTS:
            raise LiveError(f"a live session shows 1 to {MAX_ROBOTS} robots, got {len(robots)}")
        n_starts = len(arena.start_poses)
        if not 0 <= start < n_starts:
            raise LiveError(f"start pose must be in 0..{n_starts - 1}, got {start}")
        noise_sigma = checked_noise(noise_sigma)
        self.arena = arena
        self.start = start
        self.learning = learning or LearningSettings()
        self._lock = threading.Lock()
        self._robots: list[LiveRobot] = []
        self._pending_fault: sim.Fault | None = None
        for spec in robots:
            # Same seed for every robot: compared robots meet the same noise and random faults.
            world = new_world(
                arena, n=1, seed=seed, noise_sigma=noise_sigma, control_period=control_period
            )
            world.reset(arena.start_poses[start : start + 1])
            # Copy: online learning changes the individual, the caller's stays as loaded.
            population = spec.family.copies(spec.population, 1)
            self._robots.append(LiveRobot(spec.label, spec.family, population, world, seed))

    @property
    def lock(self) -> threading.Lock:
        return self._lock

    @property
    def robots(self) -> tuple[LiveRobot, ...]:
        return tuple(self._robots)

    def step(self, n: int = 1) -> None:
        """Advance every robot by `n` control steps."""
        with self._lock:
            self._apply_pending_fault()
            for _ in range(n):
                for robot in self._robots:
                    robot.step(self.learning)
                self._apply_pending_fault()

    def _apply_pending_fault(self) -> None:
        pending = self._pending_fault
        if pending is not None and self._robots[0].t >= pending.step:
            for robot in self._robots:
                robot.break_sensors(pending.sensors, pending.mode)
            self._pending_fault = None

    def schedule_fault(self, step: int, sensors: Sequence[int], mode: str) -> None:
        """Break `sensors` of every robot when they reach control step `step` (t').

        Raises:
            sim.WorldError: a bad step, sensor or mode (checked now, not when it fires).
        """
        fault = sim.Fault(step=step, sensors=tuple(sensors), mode=cast(FaultMode, mode))
        with self._lock:
            self._pending_fault = fault

    def snapshot(self) -> tuple[RobotSnapshot, ...]:
        with self._lock:
            return tuple(robot.snapshot() for robot in self._robots)

    def set_noise(self, sigma: float) -> None:
        """Sensor noise σ of every robot (see `checked_noise`)."""
        sigma = checked_noise(sigma)
        with self._lock:
            for robot in self._robots:
                robot.world.noise_sigma = sigma

    def break_sensors(self, sensors: Sequence[int], mode: str) -> None:
        """Break `sensors` of every robot on show now, in fault `mode`.

        Raises:
            sim.WorldError: a bad sensor or mode; the first robot's world refuses it before
                any robot changes.
        """
        with self._lock:
            for robot in self._robots:
                robot.break_sensors(sensors, cast(FaultMode, mode))

    def repair(self) -> None:
        with self._lock:
            for robot in self._robots:
                robot.repair()

    def set_learning(self, learning: LearningSettings) -> None:
        with self._lock:
            self.learning = learning
