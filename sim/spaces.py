"""The pymunk side of the world: where the copies of an arena go so that every copy rounds
alike, and ``Chunk``, one pymunk space of robots, each alone in its copy, moved by forces."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pymunk
import pymunk.batch as pb

from sim import drive
from sim.arena import Arena
from sim.khepera import BODY_RADIUS_MM, MASS, MOMENT

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
visits one to four small cells, and few cells per copy are easy to keep apart (see
``copy_layout``)."""
HASH_BINS = 6151
"""Bins of a space's spatial hash. A prime from chipmunk's table of hash sizes, so the hash
has exactly this many bins (chipmunk rounds a requested size up to its table); clearing the
robots' hash every substep costs time in proportion to it."""
SOLVER_ITERATIONS = 5
"""Contact solver iterations (chipmunk's default is 10): a disc against one or two frictionless
walls converges in a few; measured, fewer iterations leave the penetration unchanged."""

_POSE_FIELDS = pb.BodyFields.POSITION | pb.BodyFields.ANGLE
_DRIVE_FIELDS = pb.BodyFields.FORCE | pb.BodyFields.TORQUE


class Chunk:
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
        # pattern of cells, and no two cells of one copy share a bin (see ``copy_layout``), so a
        # robot meets its own copy's walls in the same order in every copy.
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
        drive.drive_forces(angles, spins, commands, self.rows, dt, self.forces, drive.turns_for(dt))
        for buffer in self.set_buffers:
            pb.set_space_bodies(self.space, _DRIVE_FIELDS, buffer)
            self.space.step(dt)


def hash_bin(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """The bin of cell (i, j) in chipmunk's spatial hash (cpSpaceHash.c's hash_func)."""
    i, j = i.astype(np.uint64), j.astype(np.uint64)
    return ((i * np.uint64(1640531513)) ^ (j * np.uint64(2654435789))) % np.uint64(HASH_BINS)


def copy_layout(arena: Arena, count: int) -> tuple[np.ndarray, int, int]:
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
    bins = hash_bin(
        first + col[:, None] * side + di[None, :], first + row[:, None] * side + dj[None, :]
    )
    bins.sort(axis=1)
    kept = np.flatnonzero(np.all(bins[:, 1:] != bins[:, :-1], axis=1))
    slots = kept[np.arange(count) % len(kept)]
    origin = np.array([lo + COPY_MARGIN_MM - np.floor(xmin), lo + COPY_MARGIN_MM - np.floor(ymin)])
    offsets = origin + np.stack([col[slots], row[slots]], axis=1) * (side * cell)
    return offsets.astype(np.float64), len(kept), cell
