"""A batch of Khepera robots, each in its own copy of an arena, in pymunk spaces."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal, cast, get_args

import numpy as np
import pymunk
import pymunk.batch as pb

from sim import drive, noise, rays
from sim.analytic import AnalyticBodies
from sim.arena import Arena
from sim.khepera import (
    BODY_RADIUS_MM,
    CONTROL_PERIOD_S,
    MASS,
    MOMENT,
    N_SENSORS,
)
from sim.loop import WorldArrays
from sim.noise import NoiseStream

FaultMode = Literal["dead", "saturated", "stuck", "random"]
FAULT_MODES: tuple[FaultMode, ...] = get_args(FaultMode)
"""Fault modes; their codes in ``World.fault_modes`` are 1..4 in this order (0 = healthy)."""
Physics = Literal["pymunk", "analytic"]
PHYSICS: tuple[Physics, ...] = get_args(Physics)
"""The world's physics: pymunk (the reference) or analytic (numba, for sweeps; see
``sim.analytic``)."""

WALL_CATEGORY = 0b01
ROBOT_CATEGORY = 0b10
WALL_FILTER = pymunk.ShapeFilter()
"""Walls keep pymunk's default filter (every category, every mask): they collide with robots."""
ROBOT_FILTER = pymunk.ShapeFilter(categories=ROBOT_CATEGORY, mask=WALL_CATEGORY)
"""Robots collide with walls only: robots in one space never touch each other."""
RAY_FILTER = pymunk.ShapeFilter(mask=WALL_CATEGORY)
"""What a sensor ray sees: walls."""

COPY_REGION_MM = (32768.0, 65536.0)
"""All copies of the arena lie in this range on both axes: there every float64 has the same
spacing (2⁻³⁷ mm), so moving a copy by a whole number of millimetres changes no rounding, and a
robot's trajectory is bit-identical whichever copy it is in."""
COPY_MARGIN_MM = 64
"""Least gap between an arena's bounds and the edge of its copy's square."""
HASH_CELLS_PER_SIDE = 5
"""A copy's square is at most this many spatial hash cells on a side: a robot's query then
visits one to four small cells, and few cells per copy are easy to keep apart (see _Layout)."""
HASH_BINS = 6151
"""Bins of a space's spatial hash. A prime from chipmunk's table of hash sizes, so the hash
has exactly this many bins (chipmunk rounds a requested size up to its table); clearing the
robots' hash every substep costs time in proportion to it."""
DEFAULT_SUBSTEPS = 3
"""Physics steps per control period. A robot at full speed moves 75 mm/s · 64 ms / 3 = 1.6 mm
per substep, which bounds how far it can enter a wall before chipmunk sees the contact."""
SOLVER_ITERATIONS = 5
"""Contact solver iterations (chipmunk's default is 10): a disc against one or two frictionless
walls converges in a few; measured, fewer iterations leave the penetration unchanged."""


_POSE_FIELDS = pb.BodyFields.POSITION | pb.BodyFields.ANGLE
_DRIVE_FIELDS = pb.BodyFields.FORCE | pb.BodyFields.TORQUE


def wrapped(poses: np.ndarray) -> np.ndarray:
    """A copy of poses (..., 3) with headings in [-π, π) (the world keeps them unwrapped)."""
    out = np.array(poses, dtype=np.float64)
    out[..., 2] = np.mod(out[..., 2] + np.pi, 2 * np.pi) - np.pi
    return out


class WorldError(ValueError):
    """Bad input to a ``World`` (shapes, ranges, sensor or robot indices, fault modes)."""


@dataclass(frozen=True)
class Fault:
    """A scheduled sensor fault.

    Attributes:
        step: The world step (``world.t``) at which the sensors break.
        sensors: Sensor indices 0..7.
        mode: ``dead`` (reads 0), ``saturated`` (1023), ``stuck`` (keeps the value it showed when
            it broke) or ``random`` (uniform in 0..1023 each step).
        robots: Robot indices, or None for every robot.
    """

    step: int
    sensors: tuple[int, ...]
    mode: FaultMode = "dead"
    robots: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if isinstance(self.step, bool) or not isinstance(self.step, int | np.integer):
            raise WorldError(f"Fault.step must be an int, got {self.step!r}")
        if self.step < 0:
            raise WorldError(f"Fault.step must be ≥ 0, got {self.step}")
        object.__setattr__(self, "sensors", tuple(int(s) for s in _check_sensors(self.sensors)))
        _mode_code(self.mode)
        if self.robots is not None:
            object.__setattr__(self, "robots", tuple(int(r) for r in self.robots))


def _check_sensors(sensors: int | Iterable[int]) -> np.ndarray:
    items = [sensors] if isinstance(sensors, int | np.integer) else list(sensors)
    if not items:
        raise WorldError("no sensors given: expected indices in 0..7")
    for s in items:
        if isinstance(s, bool) or not isinstance(s, int | np.integer) or not 0 <= s < N_SENSORS:
            raise WorldError(f"sensor index {s!r} is not in 0..{N_SENSORS - 1}")
    return np.array(items, dtype=np.int64)


def _mode_code(mode: str) -> int:
    if mode not in FAULT_MODES:
        raise WorldError(f"unknown fault mode {mode!r}: expected one of {', '.join(FAULT_MODES)}")
    return FAULT_MODES.index(cast(FaultMode, mode)) + 1


class _Chunk:
    """One pymunk space holding a run of robots, each with its own copy of the arena."""

    def __init__(self, arena: Arena, offsets: np.ndarray, cell: int) -> None:
        self.offsets = offsets
        self.space = pymunk.Space()
        self.space.damping = 0.0  # velocity = force·dt/m each substep: the force drive
        self.space.gravity = (0.0, 0.0)
        self.space.iterations = SOLVER_ITERATIONS
        # Chipmunk solves a body's contacts in the order the broadphase found them, and that
        # order decides the last bits of a robot pressed into a corner. The default BB tree's
        # order depends on every copy in the space. In this spatial hash every copy has the same
        # pattern of cells, and no two cells of one copy share a bin (see _layout), so a robot
        # meets its own copy's walls in the same order in every copy.
        self.space.use_spatial_hash(cell, HASH_BINS)
        # pymunk's defaults are what the walls need: no friction, no bounce, WALL_FILTER.
        static = self.space.static_body
        self.space.add(
            *(
                pymunk.Segment(static, (ax, ay), (bx, by), 0.0)
                for offset in offsets
                for (ax, ay), (bx, by) in (arena.walls + offset).tolist()
            )
        )
        self.bodies: list[pymunk.Body | None] = [None] * len(offsets)
        self.shapes: list[pymunk.Circle | None] = [None] * len(offsets)
        self.ids: dict[int, int] = {}  # pymunk body id -> robot
        self.buffer = pb.Buffer()  # for reading; chipmunk owns (and grows) its arrays
        self.rows = np.arange(len(offsets))  # buffer row of each robot
        self.forces = np.zeros((0, 0, 3))  # (substeps, bodies, 3)
        self.set_buffers: list[pb.Buffer] = []  # one per substep, each pointing into forces

    def place(self, local: Sequence[int], poses: np.ndarray) -> None:
        """Remove robots ``local`` and add them back, at rest, at arena-local ``poses``."""
        for i, pose in zip(local, poses, strict=True):
            old_body, old_shape = self.bodies[i], self.shapes[i]
            if old_body is not None and old_shape is not None:
                self.space.remove(old_body, old_shape)
                del self.ids[old_body.id]
            # A new body: a reused one would carry chipmunk's contact bias velocity along.
            body = pymunk.Body(MASS, MOMENT)
            body.position = (pose[0] + self.offsets[i, 0], pose[1] + self.offsets[i, 1])
            body.angle = pose[2]
            shape = pymunk.Circle(body, BODY_RADIUS_MM)
            shape.filter = ROBOT_FILTER  # friction and elasticity stay at pymunk's default, 0
            self.space.add(body, shape)
            self.bodies[i], self.shapes[i] = body, shape
            self.ids[body.id] = i
        # Removing and adding bodies reorders them in the space: map robots to buffer rows.
        self.buffer.clear()
        pb.get_space_bodies(self.space, pb.BodyFields.BODY_ID, self.buffer)
        ids = np.frombuffer(self.buffer.int_buf(), dtype=np.uintp)
        for row, body_id in enumerate(ids):
            robot = self.ids.get(int(body_id))
            if robot is not None:
                self.rows[robot] = row
        self.forces = np.zeros((0, len(ids), 3))

    def read_poses(self, out: np.ndarray) -> None:
        """Arena-local poses of this chunk's robots into out (n, 3)."""
        self.buffer.clear()
        pb.get_space_bodies(self.space, _POSE_FIELDS, self.buffer)
        drive.gather_poses(np.frombuffer(self.buffer.float_buf()), self.rows, self.offsets, out)

    def advance(
        self, angles: np.ndarray, spins: np.ndarray, commands: np.ndarray, dt: float, substeps: int
    ) -> None:
        """Drive the robots through ``substeps`` physics steps of ``dt``."""
        if self.forces.shape[0] != substeps:
            self.forces = np.zeros((substeps, self.forces.shape[1], 3))
            self.set_buffers = []
            for forces in self.forces:
                buffer = pb.Buffer()
                buffer.set_float_buf(forces.reshape(-1))
                self.set_buffers.append(buffer)
        drive.drive_forces(angles, spins, commands, self.rows, dt, self.forces)
        for buffer in self.set_buffers:
            pb.set_space_bodies(self.space, _DRIVE_FIELDS, buffer)
            self.space.step(dt)


def _hash_bin(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """The bin of cell (i, j) in chipmunk's spatial hash (cpSpaceHash.c's hash_func)."""
    i, j = i.astype(np.uint64), j.astype(np.uint64)
    return ((i * np.uint64(1640531513)) ^ (j * np.uint64(2654435789))) % np.uint64(HASH_BINS)


def _layout(arena: Arena, count: int) -> tuple[np.ndarray, int, int]:
    """Where the copies of the arena go.

    The region ``COPY_REGION_MM`` is tiled with squares of whole hash cells (a power of two in
    mm, so chipmunk's cell of a point, floor(x / cell), shifts by whole cells with the copy).
    A square is kept for a copy only if no two of its cells fall in the same hash bin: then a
    bin holds, of that copy's walls, only those of one cell, in the order they were added.

    Returns:
        Whole-millimetre offsets of ``count`` copies (filling the squares in order, and again
        in the next space), how many copies a space holds, and the hash cell side in mm.
    """
    xmin, ymin, xmax, ymax = arena.bounds
    span = max(np.ceil(xmax) - np.floor(xmin), np.ceil(ymax) - np.floor(ymin)) + 2 * COPY_MARGIN_MM
    # A copy spans the closed interval [start, start + span] from a cell boundary: floor(span /
    # cell) + 1 cells, so the cell must exceed span / cells-per-side strictly (a span of exactly
    # whole cells would reach one cell further: found by hypothesis for a 100 x 512 mm box). For
    # the shipped arenas (span / 5 = 225.6 mm) this is the cell and side it always was.
    cell = 1 << (int(np.floor(np.log2(span / HASH_CELLS_PER_SIDE))) + 1)
    side = int(span // cell) + 1  # cells per square side
    lo, hi = COPY_REGION_MM
    first, per_axis = int(lo) // cell, int(hi - lo) // (side * cell)
    col, row = np.divmod(np.arange(per_axis * per_axis), per_axis)
    di, dj = np.divmod(np.arange(side * side), side)
    bins = _hash_bin(
        first + col[:, None] * side + di[None, :], first + row[:, None] * side + dj[None, :]
    )
    bins.sort(axis=1)
    kept = np.flatnonzero(np.all(bins[:, 1:] != bins[:, :-1], axis=1))
    slots = kept[np.arange(count) % len(kept)]
    origin = np.array([lo + COPY_MARGIN_MM - np.floor(xmin), lo + COPY_MARGIN_MM - np.floor(ymin)])
    offsets = origin + np.stack([col[slots], row[slots]], axis=1) * (side * cell)
    return offsets.astype(np.float64), len(kept), cell


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
        physics: Physics = "pymunk",
        noise_stream: NoiseStream = "box-muller-v1",
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
        offsets, capacity, cell = _layout(arena, self.n)
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
            _Chunk(arena, offsets[start : start + capacity], cell)
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
        which = _check_sensors(sensors)
        code = _mode_code(mode)
        index = self._robot_index(robots)
        if code == FAULT_MODES.index("stuck") + 1:
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
        which = np.arange(N_SENSORS) if sensors is None else _check_sensors(sensors)
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
