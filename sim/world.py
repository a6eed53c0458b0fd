"""A batch of Khepera robots, each in its own copy of an arena, in pymunk spaces (``sim.spaces``)
or moved by the analytic physics (``sim.analytic``)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import pymunk

from sim import drive, noise, rays
from sim.analytic import AnalyticBodies
from sim.arena import Arena
from sim.faults import (
    STUCK_CODE,
    Fault,
    FaultMode,
    WorldError,
    check_sensors,
    mode_code,
)
from sim.khepera import BODY_RADIUS_MM, CONTROL_PERIOD_S, N_SENSORS
from sim.kinds import DEFAULT_NOISE_STREAM, DEFAULT_PHYSICS, PHYSICS, NoiseStream, Physics
from sim.loop import WorldArrays
from sim.spaces import SOLVER_ITERATIONS, Chunk, copy_layout

DEFAULT_SUBSTEPS = 3
"""Physics steps per control period. A robot at full speed moves 75 mm/s · 64 ms / 3 = 1.6 mm
per substep, which bounds how far it can enter a wall before chipmunk sees the contact."""


def wrapped(poses: np.ndarray) -> np.ndarray:
    """A copy of poses (..., 3) with headings in [-π, π) (the world keeps them unwrapped)."""
    out = np.array(poses, dtype=np.float64)
    out[..., 2] = np.mod(out[..., 2] + np.pi, 2 * np.pi) - np.pi
    return out


class World:
    """N Khepera I robots, each alone in its own copy of an arena.

    Poses in and out are arena-local: x mm, y mm, heading rad (0 = +x, counter-clockwise).
    A robot's trajectory and random draws depend only on its own pose, commands and seed, never
    on the other robots in the batch.

    Args:
        arena: The arena.
        n: Number of robots.
        seed: World seed; the default per-robot seeds derive from it (see ``reset``).
        noise_sigma: σ of the Gaussian sensor noise of Eq. 2.6 (reading units), settable.
        control_period: Simulated seconds per ``step``.
        substeps: Physics steps per control period.
        physics: ``pymunk`` (the reference) or ``analytic`` (sim.analytic: no pymunk space).
        noise_stream: How the noise's normals are drawn (``sim.NOISE_STREAMS``): the default
            ``box-muller-v1`` gives every earlier run's bits, ``ziggurat-v1`` is faster and
            draws other numbers from the same distribution.
    """

    def __init__(
        self,
        arena: Arena,
        n: int = 300,
        seed: int = 0,
        noise_sigma: float = 0.0,
        control_period: float = CONTROL_PERIOD_S,
        substeps: int = DEFAULT_SUBSTEPS,
        physics: Physics = DEFAULT_PHYSICS,
        noise_stream: NoiseStream = DEFAULT_NOISE_STREAM,
    ) -> None:
        if not isinstance(arena, Arena):
            raise WorldError(f"arena must be a sim.Arena (see sim.load_arena), got {arena!r}")
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise WorldError(f"n (number of robots) must be a positive int, got {n!r}")
        if not (isinstance(control_period, int | float) and 0 < control_period < np.inf):
            raise WorldError(f"control_period must be > 0 seconds, got {control_period!r}")
        if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
            raise WorldError(f"substeps must be a positive int, got {substeps!r}")
        if physics not in PHYSICS:
            raise WorldError(f"unknown physics {physics!r}: expected one of {', '.join(PHYSICS)}")
        self.physics = physics
        try:
            self._noise_stream = noise.noise_stream_code(noise_stream)
        except ValueError as error:
            raise WorldError(str(error)) from None
        self.noise_stream = noise_stream
        self.arena = arena
        self.n = int(n)
        self.seed = int(seed)
        self.control_period = float(control_period)
        self.substeps = substeps
        self.noise_sigma = noise_sigma
        offsets, capacity, cell = copy_layout(arena, self.n)
        self._wall_grid = arena.wall_grid
        # Analytic: every robot in the first copy's frame (copies round alike), no spaces.
        self._analytic = (
            AnalyticBodies(
                arena.walls, self.n, offsets[0], SOLVER_ITERATIONS, cell, arena.wall_grid
            )
            if physics == "analytic"
            else None
        )
        self._chunks = [
            Chunk(arena, offsets[start : start + capacity], cell)
            for start in range(0, self.n, capacity)
            if self._analytic is None
        ]
        self._capacity = capacity
        self._poses = np.zeros((self.n, 3))
        self._readings = np.zeros((self.n, N_SENSORS))
        self._observed = np.zeros((self.n, N_SENSORS))
        self._commands = np.zeros((self.n, 2))
        self._spins = np.zeros(self.n)  # angular velocity the bodies carry into the next step
        self._fault_mode = np.zeros((self.n, N_SENSORS), dtype=np.int8)
        self._stuck = np.zeros((self.n, N_SENSORS))
        self._schedule: list[Fault] = []
        self._episode = 0
        self._seeds = np.zeros(self.n, dtype=np.uint64)
        self._keys = np.zeros(self.n, dtype=np.uint64)
        self._fresh = False
        self.t = 0
        self.reset(np.resize(arena.start_poses, (self.n, 3)))

    # --- state ---

    @property
    def noise_sigma(self) -> float:
        """σ of the sensor noise (reading units); 0 turns it off."""
        return self._noise_sigma

    @noise_sigma.setter
    def noise_sigma(self, value: float) -> None:
        try:
            sigma = float(value)
        except (TypeError, ValueError):
            sigma = float("nan")
        if not (np.isfinite(sigma) and sigma >= 0):
            raise WorldError(f"noise_sigma must be a finite number ≥ 0, got {value!r}")
        self._noise_sigma = sigma

    @property
    def poses(self) -> np.ndarray:
        """(N, 3) arena-local poses: x mm, y mm, heading rad in [-π, π)."""
        return wrapped(self._poses)

    @property
    def seeds(self) -> np.ndarray:
        """(N,) uint64 per-robot seeds of the current episode."""
        return self._seeds.copy()

    @property
    def broken(self) -> np.ndarray:
        """(N, 8) bool: which sensors are broken."""
        return self._fault_mode > 0

    @property
    def fault_modes(self) -> np.ndarray:
        """(N, 8) int8: 0 healthy, else 1 + the index of the mode in ``FAULT_MODES``."""
        return self._fault_mode.copy()

    @property
    def schedule(self) -> tuple[Fault, ...]:
        """Scheduled faults (they persist across resets)."""
        return tuple(self._schedule)

    # --- episode control ---

    def reset(self, poses: np.ndarray, seeds: np.ndarray | Sequence[int] | None = None) -> None:
        """Start an episode: place every robot at rest, repair all sensors, set ``t`` to 0.

        Args:
            poses: (N, 3) arena-local start poses.
            seeds: (N,) non-negative ints, each robot's random stream (noise, random faults).
                Default: derived from (world seed, episode number, robot index), so every reset
                draws fresh noise. Pass ``world.seeds[i]`` to replay robot i elsewhere.
        """
        poses = self._check_poses(poses, self.n)
        if seeds is None:
            new_seeds = noise.derive_seeds(
                np.uint64(self.seed % 2**64), np.uint64(self._episode), self.n
            )
        else:
            raw = np.asarray(seeds)
            if raw.shape != (self.n,) or not np.issubdtype(raw.dtype, np.integer):
                raise WorldError(f"seeds must be {self.n} ints, got shape {raw.shape} {raw.dtype}")
            if np.any(raw < 0):
                raise WorldError("seeds must be ≥ 0")
            new_seeds = raw.astype(np.uint64)
        self._episode += 1
        self._seeds = new_seeds
        self._keys = noise.robot_keys(new_seeds)
        self.t = 0
        self._fault_mode[:] = 0
        self._stuck[:] = 0.0
        self._place_all(np.arange(self.n), poses)
        self._fire_scheduled()

    def place(self, poses: np.ndarray, robots: Sequence[int] | np.ndarray | None = None) -> None:
        """Move robots to new poses, at rest, keeping the clock, faults and random streams.

        Args:
            poses: (R, 3) arena-local poses for the R chosen robots.
            robots: Robot indices; None for all.
        """
        index = self._robot_index(robots)
        self._place_all(index, self._check_poses(poses, len(index)))

    def _place_all(self, index: np.ndarray, poses: np.ndarray) -> None:
        self._spins[index] = 0.0
        if self._analytic is not None:
            self._analytic.place(index, poses)
        cap = self._capacity
        for c, chunk in enumerate(self._chunks):
            mine = (index >= c * cap) & (index < (c + 1) * cap)
            if np.any(mine):
                chunk.place(list(index[mine] - c * cap), poses[mine])
        self._read_poses()

    def _check_poses(self, poses: np.ndarray, count: int) -> np.ndarray:
        poses = np.array(poses, dtype=np.float64)
        if poses.shape != (count, 3):
            raise WorldError(f"poses must have shape ({count}, 3), got {poses.shape}")
        if not np.all(np.isfinite(poses)):
            raise WorldError("poses contain NaN or infinity")
        free = self.arena.contains(poses[:, :2]) & (
            self.arena.clearance(poses[:, :2]) > BODY_RADIUS_MM
        )
        if not np.all(free):
            bad = int(np.argmin(free))
            raise WorldError(
                f"pose {bad} {tuple(poses[bad])} is not in free space of arena "
                f"{self.arena.name!r}: the robot (radius {BODY_RADIUS_MM} mm) must be inside "
                "the outer wall, outside obstacles and clear of every wall"
            )
        return poses

    def _robot_index(self, robots: Sequence[int] | np.ndarray | None) -> np.ndarray:
        if robots is None:
            return np.arange(self.n)
        index = np.asarray(robots)
        if index.dtype == bool:
            if index.shape != (self.n,):
                raise WorldError(f"a robot mask must have shape ({self.n},), got {index.shape}")
            return np.flatnonzero(index)
        index = index.reshape(-1)
        if index.size and not np.issubdtype(index.dtype, np.integer):
            raise WorldError(f"robot indices must be ints, got {index.dtype}")
        index = index.astype(np.int64)
        if np.any((index < 0) | (index >= self.n)):
            raise WorldError(f"robot indices must be in 0..{self.n - 1}, got {index.tolist()}")
        if len(np.unique(index)) != len(index):
            raise WorldError(f"robot indices repeat: {index.tolist()}")
        return index  # in the caller's order: place() pairs them with poses

    def _read_poses(self) -> None:
        if self._analytic is not None:
            self._analytic.read_poses(self._poses)
        cap = self._capacity
        for c, chunk in enumerate(self._chunks):
            chunk.read_poses(self._poses[c * cap : c * cap + len(chunk.offsets)])
        self._fresh = False

    # --- sensing and acting ---

    def sense(self) -> np.ndarray:
        """(N, 8) true IR readings s0..s7 in 0..1023 (no noise, no fault)."""
        self._update_readings()
        return self._readings.copy()

    def _update_readings(self) -> None:
        if not self._fresh:
            grid = self._wall_grid  # the kernel itself: sensors.ir_readings without its checks
            rays.ir_readings_grid(
                self._poses, grid.table, grid.frame, grid.starts, grid.members, self._readings
            )
            self._fresh = True

    def observe(self) -> np.ndarray:
        """(N, 8) what the controller sees: true readings, Eq. 2.6 noise, then faults.

        Draws are a function of (robot seed, ``t``, sensor): observing twice in a step gives the
        same values.
        """
        self._update_readings()
        noise.observe(
            self._readings,
            self._keys,
            np.uint64(self.t),
            self._noise_sigma,
            self._fault_mode,
            self._stuck,
            self._observed,
            self._noise_stream,
        )
        return self._observed.copy()

    def step(self, commands: np.ndarray) -> None:
        """Advance one control period.

        Args:
            commands: (N, 2) left, right wheel commands (rad/s), clipped to −10..10.
        """
        raw = np.asarray(commands, dtype=np.float64)
        if raw.shape != (self.n, 2):
            raise WorldError(f"commands must have shape ({self.n}, 2), got {raw.shape}")
        if not drive.clip_commands(raw, self._commands):
            raise WorldError("commands contain NaN")
        dt = self.control_period / self.substeps
        if self._analytic is not None:
            self._analytic.advance(
                self._poses[:, 2], self._spins, self._commands, dt, self.substeps
            )
            self._analytic.read_poses(self._poses)
        cap = self._capacity
        for c, chunk in enumerate(self._chunks):
            part = slice(c * cap, c * cap + len(chunk.offsets))
            chunk.advance(
                self._poses[part, 2], self._spins[part], self._commands[part], dt, self.substeps
            )
            chunk.read_poses(self._poses[part])
        drive.wheel_spins(self._commands, self._spins)
        self._fresh = False
        self.t += 1
        self._fire_scheduled()

    # --- a compiled loop's view (sim.loop) ---

    def arrays(self) -> WorldArrays:
        """The world's own arrays (views, not copies), its readings up to date, for a loop
        compiled around ``sim.loop``'s functions; analytic physics only."""
        if self._analytic is None:
            raise WorldError("only an analytic world steps in compiled code (pymunk steps in C)")
        self._update_readings()
        grid = self._wall_grid
        return WorldArrays(
            self._poses,
            self._readings,
            self._observed,
            self._commands,
            self._spins,
            self._fault_mode,
            self._stuck,
            self._keys,
            self._noise_sigma,
            self._noise_stream,
            grid.table,
            grid.frame,
            grid.starts,
            grid.members,
            self._analytic.arrays(self.control_period / self.substeps, self.substeps),
        )

    @property
    def fault_steps(self) -> frozenset[int]:
        """The clock values at which scheduled faults fire."""
        return frozenset(f.step for f in self._schedule)

    def stepped(self, steps: int) -> None:
        """Account for ``steps`` steps a compiled loop took on ``arrays()``, its last one
        sensed: the clock moves on; no scheduled fault may fire on the way."""
        if any(self.t < s <= self.t + steps for s in self.fault_steps):
            raise WorldError("a fault fires within the steps: step through it by World.step")
        self.t += steps
        self._fresh = True

    # --- faults ---

    def break_sensors(
        self,
        sensors: int | Iterable[int],
        mode: FaultMode = "dead",
        robots: Sequence[int] | np.ndarray | None = None,
    ) -> None:
        """Break sensors now (between two steps).

        Args:
            sensors: Sensor index or indices in 0..7.
            mode: ``dead``, ``saturated``, ``stuck`` or ``random``.
            robots: Robot indices or an (N,) bool mask; None for all.
        """
        which = check_sensors(sensors)
        code = mode_code(mode)
        index = self._robot_index(robots)
        if code == STUCK_CODE:
            seen = self.observe()
            rows = np.ix_(index, which)
            self._stuck[rows] = seen[rows]
        self._fault_mode[np.ix_(index, which)] = code

    def repair(
        self,
        robots: Sequence[int] | np.ndarray | None = None,
        sensors: int | Iterable[int] | None = None,
    ) -> None:
        """Repair sensors (all of them by default) of the given robots (all by default)."""
        index = self._robot_index(robots)
        which = np.arange(N_SENSORS) if sensors is None else check_sensors(sensors)
        self._fault_mode[np.ix_(index, which)] = 0

    def schedule_faults(self, faults: Iterable[Fault]) -> None:
        """Replace the fault schedule. A fault fires when ``t`` reaches its step, in this and
        every later episode; one whose step is now or past fires at once."""
        faults = list(faults)
        for f in faults:
            if not isinstance(f, Fault):
                raise WorldError(f"schedule_faults takes sim.Fault objects, got {f!r}")
            if f.robots is not None:
                self._robot_index(list(f.robots))
        self._schedule = faults
        for f in faults:
            if f.step <= self.t:
                self.break_sensors(f.sensors, f.mode, f.robots)

    def _fire_scheduled(self) -> None:
        for f in self._schedule:
            if f.step == self.t:
                self.break_sensors(f.sensors, f.mode, f.robots)

    # --- views for the dashboard and the tests ---

    def space_of(self, robot: int) -> tuple[pymunk.Space, np.ndarray]:
        """The pymunk space holding a robot and its copy offset (for oracles and debugging)."""
        if self._analytic is not None:
            raise WorldError("an analytic world has no pymunk space")
        chunk = self._chunks[robot // self._capacity]
        return chunk.space, chunk.offsets[robot % self._capacity]
