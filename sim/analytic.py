"""The analytic physics: each robot a disc against its arena's wall segments, in numba.

No pymunk space. A robot is a point state (position, heading, velocity, the contact solver's
bias velocity) moved by the same force drive as the pymunk world (``sim.drive.drive_forces``),
and its contacts with the walls are found and solved here, one robot at a time. The contact
model is chipmunk's, restricted to what this world uses (a disc against static, frictionless,
inelastic segments; see docs/decisions.md): a contact exists while the disc's centre is closer
than its radius to a segment; each substep the solver removes the velocity into the wall and
adds a bias velocity that takes back ``1 − COLLISION_BIAS^dt`` of the penetration beyond
``COLLISION_SLOP_MM``; accumulated impulses are kept per (robot, wall) pair and warm-start the
next substep, with chipmunk's persistence rules. The arithmetic follows chipmunk's operation by
operation, and a robot's contacts are solved in the order the pymunk world's spatial hash
finds them (by the first hash cell they share with the robot, then the latest-added wall
first), so that where several walls touch a robot the solver's passes round alike too.

Positions are kept in a copy of the arena at the same kind of offset as the pymunk world's
(``sim.spaces.COPY_REGION_MM``), so their rounding is the pymunk world's too.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numba as nb
import numpy as np

from sim import drive, khepera, rays, sensors
from sim.kernel_cache import drop_stale_cache, source_fingerprint
from sim.khepera import BODY_RADIUS_MM, MASS, MOMENT
from sim.sensors import WallGrid

COLLISION_SLOP_MM = float(np.float32(0.1))
"""Penetration the contact solver leaves alone (chipmunk's default, a C float 0.1f)."""
COLLISION_BIAS = float(np.float32(1.0) - np.float32(0.1)) ** 60.0
"""Fraction of the penetration left after one second of correction (chipmunk's default,
(1 − 0.1f)^60: 10% corrected per 1/60 s)."""
COLLISION_PERSISTENCE = 3
"""Physics steps a contact's accumulated impulse is remembered after it ends (chipmunk's)."""
MAX_REMEMBERED = 8
"""Contacts a robot remembers at once; more walls than this within a body radius in three
substeps cannot happen in a room of straight walls (a point touches at most a few)."""

REACH_MM = rays.REACH_MM
"""Every wall this close to a robot's centre is listed for its grid cell (``sim.sensors``)."""
FLIGHT_MARGIN_MM = 1.0
"""How much farther than its radius plus the most it can move in a period a robot's nearest wall
must be for the robot to fly free of the contact solver for that period (``solve_discs``): the
margin dwarfs the rounding of the distances (1e-12 mm at the copy frame's coordinates)."""

_X, _Y, _A, _VX, _VY, _W, _BX, _BY, _BW = range(9)
"""Columns of the state: position, heading, velocity, angular velocity, bias velocities."""


class AnalyticBodies:
    """The bodies of N robots, each alone with its own arena's walls.

    Args:
        walls: (K, 2, 2) wall segments, arena-local mm.
        n: Number of robots.
        offset: (2,) whole-millimetre offset of the arena copy the robots move in.
        iterations: Contact solver iterations per substep.
        cell: Side (mm) of the pymunk world's spatial hash cells: the contacts' order.
        grid: The walls' ``WallGrid`` (arena-local): a cell lists every wall within a sensor's
            reach of its points, so every wall a body in it can touch.
    """

    def __init__(
        self,
        walls: np.ndarray,
        n: int,
        offset: np.ndarray,
        iterations: int,
        cell: float,
        grid: WallGrid,
    ) -> None:
        self.grid = grid
        self.offset = np.asarray(offset, dtype=np.float64)
        copy = walls + self.offset  # the same float64 sums as the pymunk world's segments
        delta = copy[:, 1] - copy[:, 0]
        low, high = copy.min(axis=1), copy.max(axis=1)  # the wall's bounding box
        first_cell = np.floor(low / cell)  # the wall's lowest hash cell (i, j)
        self.walls = np.ascontiguousarray(
            np.column_stack(
                [copy[:, 0], delta, np.einsum("ij,ij->i", delta, delta), first_cell, low, high]
            )
        )
        self.cell = float(cell)
        self.iterations = iterations
        self.state = np.zeros((n, 9))
        self.stamps = np.zeros(n, dtype=np.int64)  # physics steps since placed
        self.seen_wall = np.full((n, MAX_REMEMBERED), -1, dtype=np.int64)
        self.seen_impulse = np.zeros((n, MAX_REMEMBERED))
        self.seen_stamp = np.zeros((n, MAX_REMEMBERED), dtype=np.int64)
        self.rows = np.arange(n)
        self.forces = np.zeros((0, n, 3))
        self.free_flight = True
        """Robots far from every wall skip the contact search (``solve_discs``); False sends
        every robot through it (the same bits: the tests compare the two)."""

    def place(self, index: Sequence[int] | np.ndarray, poses: np.ndarray) -> None:
        """Put robots ``index`` at rest at arena-local ``poses``, forgetting their contacts."""
        index = np.asarray(index, dtype=np.int64)
        poses = np.asarray(poses, dtype=np.float64)
        self.state[index] = 0.0
        self.state[index, _X] = poses[:, 0] + self.offset[0]
        self.state[index, _Y] = poses[:, 1] + self.offset[1]
        self.state[index, _A] = poses[:, 2]
        self.stamps[index] = 0
        self.seen_wall[index] = -1

    def read_poses(self, out: np.ndarray) -> None:
        """Arena-local poses (N, 3) into out."""
        read_local_poses(self.state, self.offset, out)

    def arrays(self, dt: float, substeps: int) -> BodyArrays:
        """The bodies' own arrays (views, not copies) and solver settings, for ``move``."""
        if self.forces.shape[0] != substeps:
            self.forces = np.zeros((substeps, len(self.rows), 3))
        return BodyArrays(
            self.state,
            self.forces,
            self.walls,
            self.cell,
            dt,
            1.0 - COLLISION_BIAS**dt,  # chipmunk's bias coefficient for a step of dt
            self.iterations,
            np.array([BODY_RADIUS_MM, 1.0 / MASS, 1.0 / MOMENT, COLLISION_SLOP_MM]),
            COLLISION_PERSISTENCE,
            self.stamps,
            self.seen_wall,
            self.seen_impulse,
            self.seen_stamp,
            self.rows,
            self.offset,
            self.grid.frame,
            self.grid.starts,
            self.grid.members,
            self.free_flight,
            drive.turns_for(dt),
        )

    def advance(
        self, angles: np.ndarray, spins: np.ndarray, commands: np.ndarray, dt: float, substeps: int
    ) -> None:
        """Drive the robots through ``substeps`` physics steps of ``dt`` (as ``World.step``)."""
        move(self.arrays(dt, substeps), angles, spins, commands)


class BodyArrays(NamedTuple):
    """What ``move`` reads and updates: an ``AnalyticBodies``' arrays and solver settings
    (``solve_discs`` describes them), one argument for compiled callers (``sim.loop``)."""

    state: np.ndarray
    forces: np.ndarray
    walls: np.ndarray
    cell: float
    dt: float
    bias_coef: float
    iterations: int
    body: np.ndarray
    persistence: int
    stamps: np.ndarray
    seen_wall: np.ndarray
    seen_impulse: np.ndarray
    seen_stamp: np.ndarray
    rows: np.ndarray
    offset: np.ndarray
    grid_frame: np.ndarray
    grid_starts: np.ndarray
    grid_members: np.ndarray
    free_flight: bool
    turns: np.ndarray  # sim.drive.turn_table(dt)


@nb.njit(cache=True)
def move(bodies: BodyArrays, angles: np.ndarray, spins: np.ndarray, commands: np.ndarray) -> None:
    """One control period of every body: the force drive, then the substeps' contacts."""
    drive.drive_forces(angles, spins, commands, bodies.rows, bodies.dt, bodies.forces, bodies.turns)
    solve_discs(
        bodies.state,
        bodies.forces,
        bodies.walls,
        bodies.cell,
        bodies.dt,
        bodies.bias_coef,
        bodies.iterations,
        bodies.body,
        bodies.persistence,
        bodies.stamps,
        bodies.seen_wall,
        bodies.seen_impulse,
        bodies.seen_stamp,
        bodies.offset,
        bodies.grid_frame,
        bodies.grid_starts,
        bodies.grid_members,
        bodies.free_flight,
    )


@nb.njit(cache=True)
def read_local_poses(state: np.ndarray, offset: np.ndarray, out: np.ndarray) -> None:
    """Arena-local poses (N, 3) into out, from body states in the copy's frame."""
    for i in range(state.shape[0]):
        out[i, 0] = state[i, _X] - offset[0]
        out[i, 1] = state[i, _Y] - offset[1]
        out[i, 2] = state[i, _A]


@nb.njit(cache=True)
def solve_discs(
    state: np.ndarray,
    forces: np.ndarray,
    walls: np.ndarray,
    cell: float,
    dt: float,
    bias_coef: float,
    iterations: int,
    body: np.ndarray,
    persistence: int,
    stamps: np.ndarray,
    seen_wall: np.ndarray,
    seen_impulse: np.ndarray,
    seen_stamp: np.ndarray,
    offset: np.ndarray,
    grid_frame: np.ndarray,
    grid_starts: np.ndarray,
    grid_members: np.ndarray,
    free_flight: bool,
) -> None:
    """Step every robot through the substeps of ``forces``, chipmunk's cpSpaceStep for one disc.

    Per substep: move by the velocity plus the bias velocity; find the contacts; set the velocity
    from the force (damping 0); warm-start the contacts that went on from the last substep;
    run ``iterations`` passes of the normal and bias impulses.

    Args:
        state: (N, 9) x, y, heading, vx, vy, ω, bias vx, bias vy, bias ω (copy frame), updated.
        forces: (S, N, 3) fx, fy, τ for S substeps.
        walls: (K, 11) ax, ay, ex, ey, |e|² of segments from a to a + e (copy frame), the
            (i, j) of the lowest hash cell each one's bounding box covers, and that box (x and y
            low, x and y high).
        cell: Hash cell side (mm).
        dt: Substep length (s).
        bias_coef: Fraction of the penetration beyond the slop corrected per substep.
        iterations: Solver passes per substep.
        body: radius, 1/mass, 1/moment, slop.
        persistence: Substeps a contact's impulse is remembered after it ends.
        stamps: (N,) substeps since each robot was placed, updated.
        seen_wall, seen_impulse, seen_stamp: (N, M) the contacts each robot remembers: wall
            (−1 for none), accumulated normal impulse and the substep it was last touched.
        offset: (2,) the copy frame's offset from the arena's.
        grid_frame, grid_starts, grid_members: the walls' ``sim.sensors.WallGrid`` (arena-local):
            a substep looks for contacts only among the walls listed for the body's cell, in
            the same ascending order; they include every wall closer than a sensor's reach, and
            a farther one holds no contact, so the contacts, their order and the bits are those
            of testing every wall. A body off the grid tests every wall.
        free_flight: let a robot whose nearest wall is farther than its radius plus the most
            it can move in the period (plus ``FLIGHT_MARGIN_MM``) skip the substeps' contact
            search, solver and bookkeeping: it has no contact in any of them, so
            it does the same floating-point operations on its motion and its memory of
            contacts ends as the bookkeeping would leave it; False: every robot goes through
            the search (the reference the tests compare with).
    """
    radius, m_inv, i_inv, slop = body[0], body[1], body[2], body[3]
    k_walls = walls.shape[0]
    cap = seen_wall.shape[1]
    # One robot's contacts in one substep: wall, n, r1, closest point (r2), nMass, bias,
    # accumulated normal and bias impulses, whether to warm-start.
    c_wall = np.empty(k_walls, dtype=np.int64)
    c_n = np.empty((k_walls, 2))
    c_r1 = np.empty((k_walls, 2))
    c_mass = np.empty(k_walls)
    c_bias = np.empty(k_walls)
    c_jn = np.empty(k_walls)
    c_jb = np.empty(k_walls)
    c_warm = np.empty(k_walls, dtype=np.bool_)
    c_key = np.empty((k_walls, 2))
    n_sub = forces.shape[0]
    for i in range(state.shape[0]):
        x, y, a = state[i, 0], state[i, 1], state[i, 2]
        vx, vy, w = state[i, 3], state[i, 4], state[i, 5]
        bx, by, bw = state[i, 6], state[i, 7], state[i, 8]
        # Free flight: no wall within its radius plus the most it can move in the period
        # (its velocity and bias velocity, then the velocities its forces set, in L1: no
        # contact changes them) plus a margin. The walls listed for its cell include every
        # one within a sensor's reach of its centre, so while that bound stays within the
        # reach a wall not listed is out of it. Written out here, not in a helper: numba's
        # reference counting on a helper's array arguments costs more than the search saves.
        free = free_flight
        if free:
            moved = abs(vx + bx) + abs(vy + by)
            for s in range(n_sub):
                moved += (abs(forces[s, i, 0]) + abs(forces[s, i, 1])) * m_inv * dt
            clear = radius + moved * dt + FLIGHT_MARGIN_MM
            col = np.floor((x - offset[0] - grid_frame[0]) / grid_frame[2])
            row = np.floor((y - offset[1] - grid_frame[1]) / grid_frame[2])
            # NaN fails every test: such a robot goes through the search
            free = clear < REACH_MM and 0.0 <= col < grid_frame[3] and 0.0 <= row < grid_frame[4]
            if free:
                near = int(row) * int(grid_frame[3]) + int(col)
                for q in range(grid_starts[near], grid_starts[near + 1]):
                    k = grid_members[q]
                    ax, ay, ex, ey = walls[k, 0], walls[k, 1], walls[k, 2], walls[k, 3]
                    if not _farther(x, y, ax, ay, ex, ey, walls[k, 4], clear * clear):
                        free = False
                        break
        if free:
            # The substeps with no contact found, operation by operation (the same bits).
            for s in range(n_sub):
                x = x + (vx + bx) * dt
                y = y + (vy + by) * dt
                a = a + (w + bw) * dt
                bx, by, bw = 0.0, 0.0, 0.0
                vx = vx * 0.0 + (0.0 + forces[s, i, 0] * m_inv) * dt
                vy = vy * 0.0 + (0.0 + forces[s, i, 1] * m_inv) * dt
                w = w * 0.0 + forces[s, i, 2] * i_inv * dt
            # Forgetting depends on the stamp alone, which only grows: checked once at the
            # last substep's stamp, it forgets what the substeps would have.
            stamp = stamps[i] + n_sub
            stamps[i] = stamp
            for q in range(cap):
                if seen_wall[i, q] >= 0 and stamp - seen_stamp[i, q] >= persistence:
                    seen_wall[i, q] = -1
            state[i, 0], state[i, 1], state[i, 2] = x, y, a
            state[i, 3], state[i, 4], state[i, 5] = vx, vy, w
            state[i, 6], state[i, 7], state[i, 8] = bx, by, bw
            continue
        for s in range(forces.shape[0]):
            stamp = stamps[i] + 1
            stamps[i] = stamp
            # cpBodyUpdatePosition
            x = x + (vx + bx) * dt
            y = y + (vy + by) * dt
            a = a + (w + bw) * dt
            bx, by, bw = 0.0, 0.0, 0.0
            # CircleToSegment for every wall, then cpArbiterUpdate and cpArbiterPreStep
            m = 0
            low_i = np.floor((x - radius) / cell)  # the robot's lowest hash cell
            low_j = np.floor((y - radius) / cell)
            col = np.floor((x - offset[0] - grid_frame[0]) / grid_frame[2])
            row = np.floor((y - offset[1] - grid_frame[1]) / grid_frame[2])
            # The cell's walls by index, not as a slice: a slice is a new array, whose
            # reference counting (two atomic operations) costs more than the loop it feeds.
            on_grid = 0.0 <= col < grid_frame[3] and 0.0 <= row < grid_frame[4]
            first, last = 0, k_walls
            if on_grid:
                near = int(row) * int(grid_frame[3]) + int(col)
                first, last = grid_starts[near], grid_starts[near + 1]
            for listed in range(first, last):
                k = grid_members[listed] if on_grid else listed
                # chipmunk's broadphase: boxes that do not overlap hold no contact
                if (
                    walls[k, 7] > x + radius
                    or walls[k, 9] < x - radius
                    or walls[k, 8] > y + radius
                    or walls[k, 10] < y - radius
                ):
                    continue
                ax, ay, ex, ey = walls[k, 0], walls[k, 1], walls[k, 2], walls[k, 3]
                t = (ex * (x - ax) + ey * (y - ay)) / walls[k, 4]
                t = 0.0 if not t > 0.0 else (1.0 if not t < 1.0 else t)
                cx = ax + ex * t
                cy = ay + ey * t
                dx = cx - x
                dy = cy - y
                distsq = dx * dx + dy * dy
                if not distsq < radius * radius:
                    continue
                dist = np.sqrt(distsq)
                if dist != 0.0:
                    inv = 1.0 / dist
                    nx, ny = dx * inv, dy * inv
                else:  # centre on the wall: push along the segment's normal
                    length = np.sqrt(walls[k, 4])
                    nx, ny = ey / length, -ex / length
                r1x = (x + nx * radius) - x
                r1y = (y + ny * radius) - y
                # The wall's static body sits at the origin: r2 is the closest point itself.
                sep = ((cx - r1x) + (0.0 - x)) * nx + ((cy - r1y) + (0.0 - y)) * ny
                rcn = r1x * ny - r1y * nx
                # The spatial hash meets this wall first in the lowest cell (i-major) that both
                # bounding boxes cover; within a cell, the wall added last comes first.
                c_key[m, 0] = max(walls[k, 5], low_i)
                c_key[m, 1] = max(walls[k, 6], low_j)
                c_wall[m] = k
                c_n[m, 0], c_n[m, 1] = nx, ny
                c_r1[m, 0], c_r1[m, 1] = r1x, r1y
                c_mass[m] = 1.0 / (m_inv + i_inv * rcn * rcn)
                d = sep + slop
                c_bias[m] = (-bias_coef * (0.0 if d > 0.0 else d)) / dt
                c_jb[m] = 0.0
                c_jn[m] = 0.0
                c_warm[m] = False
                for q in range(cap):  # the pair's remembered impulse (chipmunk's arbiter)
                    if seen_wall[i, q] == k:
                        c_jn[m] = seen_impulse[i, q]
                        c_warm[m] = seen_stamp[i, q] == stamp - 1  # else: first contact again
                m += 1
                q = m - 1  # insertion sort by (cell i, cell j, −wall)
                while q > 0 and (
                    c_key[q - 1, 0] > c_key[q, 0]
                    or (c_key[q - 1, 0] == c_key[q, 0] and c_key[q - 1, 1] > c_key[q, 1])
                    or (
                        c_key[q - 1, 0] == c_key[q, 0]
                        and c_key[q - 1, 1] == c_key[q, 1]
                        and c_wall[q - 1] < c_wall[q]
                    )
                ):
                    _swap(c_wall, c_n, c_r1, c_mass, c_bias, c_jn, c_warm, c_key, q)
                    q -= 1
            # cpBodyUpdateVelocity: damping 0, no gravity
            vx = vx * 0.0 + (0.0 + forces[s, i, 0] * m_inv) * dt
            vy = vy * 0.0 + (0.0 + forces[s, i, 1] * m_inv) * dt
            w = w * 0.0 + forces[s, i, 2] * i_inv * dt
            # cpArbiterApplyCachedImpulse
            for c in range(m):
                if c_warm[c]:
                    jx = c_n[c, 0] * c_jn[c]
                    jy = c_n[c, 1] * c_jn[c]
                    vx = vx + (-jx) * m_inv
                    vy = vy + (-jy) * m_inv
                    w += i_inv * (c_r1[c, 0] * (-jy) - c_r1[c, 1] * (-jx))
            # cpArbiterApplyImpulse, `iterations` passes (one contact, the common case, in
            # registers)
            if m == 1:
                nx, ny, r1x, r1y = c_n[0, 0], c_n[0, 1], c_r1[0, 0], c_r1[0, 1]
                mass, bias, jb, jn = c_mass[0], c_bias[0], c_jb[0], c_jn[0]
                for _ in range(iterations):
                    jb_old, jn_old = jb, jn
                    jb, jn, vx, vy, w, bx, by, bw = _impulse(
                        nx, ny, r1x, r1y, mass, bias, jb, jn, vx, vy, w, bx, by, bw, m_inv, i_inv
                    )
                    if jb == jb_old and jn == jn_old:
                        break  # a pass that changed nothing: the rest would change nothing
                c_jn[0] = jn
            else:
                for _ in range(iterations):
                    changed = False
                    for c in range(m):
                        jb_old, jn_old = c_jb[c], c_jn[c]
                        c_jb[c], c_jn[c], vx, vy, w, bx, by, bw = _impulse(
                            c_n[c, 0],
                            c_n[c, 1],
                            c_r1[c, 0],
                            c_r1[c, 1],
                            c_mass[c],
                            c_bias[c],
                            c_jb[c],
                            c_jn[c],
                            vx,
                            vy,
                            w,
                            bx,
                            by,
                            bw,
                            m_inv,
                            i_inv,
                        )
                        changed |= c_jb[c] != jb_old or c_jn[c] != jn_old
                    if not changed:
                        break
            # Remember this substep's contacts; forget those untouched for `persistence` steps.
            for c in range(m):
                slot = -1
                for q in range(cap):
                    if seen_wall[i, q] == c_wall[c]:
                        slot = q
                if slot < 0:
                    for q in range(cap):
                        if seen_wall[i, q] < 0 and slot < 0:
                            slot = q
                if slot >= 0:
                    seen_wall[i, slot] = c_wall[c]
                    seen_impulse[i, slot] = c_jn[c]
                    seen_stamp[i, slot] = stamp
            for q in range(cap):
                if seen_wall[i, q] >= 0 and stamp - seen_stamp[i, q] >= persistence:
                    seen_wall[i, q] = -1
        state[i, 0], state[i, 1], state[i, 2] = x, y, a
        state[i, 3], state[i, 4], state[i, 5] = vx, vy, w
        state[i, 6], state[i, 7], state[i, 8] = bx, by, bw


@nb.njit(cache=True, inline="always")
def _farther(
    x: float, y: float, ax: float, ay: float, ex: float, ey: float, e2: float, clear2: float
) -> bool:
    """Whether the segment from (ax, ay) to (ax + ex, ay + ey) (|e|² = e2) is farther than
    √clear2 from (x, y); False for NaN. Scalars only: a helper taking arrays costs numba's
    reference counting on each of them at every call."""
    t = (ex * (x - ax) + ey * (y - ay)) / e2
    t = 0.0 if not t > 0.0 else (1.0 if not t < 1.0 else t)
    dx = ax + ex * t - x
    dy = ay + ey * t - y
    return dx * dx + dy * dy > clear2


@nb.njit(cache=True, inline="always")
def _impulse(
    nx: float,
    ny: float,
    r1x: float,
    r1y: float,
    mass: float,
    bias: float,
    jb_acc: float,
    jn_acc: float,
    vx: float,
    vy: float,
    w: float,
    bx: float,
    by: float,
    bw: float,
    m_inv: float,
    i_inv: float,
) -> tuple[float, float, float, float, float, float, float, float]:
    """One contact's bias and normal impulses (cpArbiterApplyImpulse, no friction): the new
    accumulated impulses, velocity and bias velocity."""
    vbn = (0.0 - (bx + (-r1y) * bw)) * nx + (0.0 - (by + r1x * bw)) * ny
    vrn = (0.0 - (vx + (-r1y) * w)) * nx + (0.0 - (vy + r1x * w)) * ny
    jb_new = jb_acc + (bias - vbn) * mass
    jb_new = jb_new if jb_new > 0.0 else 0.0
    jn_new = jn_acc + (-vrn) * mass
    jn_new = jn_new if jn_new > 0.0 else 0.0
    jx = nx * (jb_new - jb_acc)
    jy = ny * (jb_new - jb_acc)
    bx = bx + (-jx) * m_inv
    by = by + (-jy) * m_inv
    bw += i_inv * (r1x * (-jy) - r1y * (-jx))
    jx = nx * (jn_new - jn_acc)
    jy = ny * (jn_new - jn_acc)
    vx = vx + (-jx) * m_inv
    vy = vy + (-jy) * m_inv
    w += i_inv * (r1x * (-jy) - r1y * (-jx))
    return jb_new, jn_new, vx, vy, w, bx, by, bw


@nb.njit(cache=True, inline="always")
def _swap(
    wall: np.ndarray,
    n: np.ndarray,
    r1: np.ndarray,
    mass: np.ndarray,
    bias: np.ndarray,
    jn: np.ndarray,
    warm: np.ndarray,
    key: np.ndarray,
    q: int,
) -> None:
    """Swap contacts q − 1 and q."""
    p = q - 1
    wall[p], wall[q] = wall[q], wall[p]
    for d in range(2):
        n[p, d], n[q, d] = n[q, d], n[p, d]
        r1[p, d], r1[q, d] = r1[q, d], r1[p, d]
        key[p, d], key[q, d] = key[q, d], key[p, d]
    mass[p], mass[q] = mass[q], mass[p]
    bias[p], bias[q] = bias[q], bias[p]
    jn[p], jn[q] = jn[q], jn[p]
    warm[p], warm[q] = warm[q], warm[p]


#: What this module's cached kernels were compiled against: sim/khepera.py's constants and
#: the modules whose kernels it calls (sim.kernel_cache).
COMPILED_AGAINST = source_fingerprint(drive, khepera, rays, sensors)


@nb.njit(cache=True)
def _frozen_sources() -> np.ndarray:
    """``COMPILED_AGAINST`` as numba froze it into this module's cache."""
    return COMPILED_AGAINST.copy()


drop_stale_cache(globals(), _frozen_sources, COMPILED_AGAINST)
