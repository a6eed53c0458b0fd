"""The world's step as compiled functions on its own arrays: the world's half of a fused loop.

`World.arrays` hands out the world's arrays (views, not copies) as a `WorldArrays`; `sense`,
`observe` and `step` here do what `World.sense`, `World.observe` and `World.step` do, by the
same kernels in the same order, so a loop compiled around them (`app.loop.fused`) gives the world's
bits. The analytic physics only (pymunk steps in C, outside numba), and no fault fires inside:
the caller steps the world by `World.step` where one does (see `World.fault_steps`), and tells
the world how many steps it took (`World.stepped`).
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np
import numpy.typing as npt

from sim import analytic, drive, faults, khepera, noise, rays, reward, sensors
from sim.kernel_cache import drop_stale_cache, source_fingerprint


class WorldArrays(NamedTuple):
    """A world's arrays and settings, one argument for compiled callers (see `World.arrays`)."""

    poses: np.ndarray  # (N, 3) arena-local, heading unwrapped
    readings: np.ndarray  # (N, 8) true readings at the poses
    observed: np.ndarray  # (N, 8) what the controllers see (noise, then faults)
    commands: np.ndarray  # (N, 2) clipped wheel commands of the last step
    spins: np.ndarray  # (N,) angular velocity carried into the next step
    fault_modes: np.ndarray  # (N, 8) int8
    stuck: np.ndarray  # (N, 8)
    keys: np.ndarray  # (N,) uint64 stream keys
    noise_sigma: float
    noise_stream: int  # the index of a sim.noise.NOISE_STREAMS name
    wall_table: np.ndarray
    grid_frame: np.ndarray
    grid_starts: np.ndarray
    grid_members: np.ndarray
    bodies: analytic.BodyArrays


@nb.njit(cache=True)
def part(world: WorldArrays, lo: int, hi: int) -> WorldArrays:
    """Robots lo..hi − 1 of a world, as a world of their own (views): robots never share
    data, so stepping the parts one after the other steps the whole world."""
    b = world.bodies
    bodies = analytic.BodyArrays(
        b.state[lo:hi],
        b.forces[:, lo:hi],
        b.walls,
        b.cell,
        b.dt,
        b.bias_coef,
        b.iterations,
        b.body,
        b.persistence,
        b.stamps[lo:hi],
        b.seen_wall[lo:hi],
        b.seen_impulse[lo:hi],
        b.seen_stamp[lo:hi],
        b.rows[: hi - lo],  # the part's own rows of its forces
        b.offset,
        b.grid_frame,
        b.grid_starts,
        b.grid_members,
        b.free_flight,
        b.turns,
    )
    return WorldArrays(
        world.poses[lo:hi],
        world.readings[lo:hi],
        world.observed[lo:hi],
        world.commands[lo:hi],
        world.spins[lo:hi],
        world.fault_modes[lo:hi],
        world.stuck[lo:hi],
        world.keys[lo:hi],
        world.noise_sigma,
        world.noise_stream,
        world.wall_table,
        world.grid_frame,
        world.grid_starts,
        world.grid_members,
        bodies,
    )


@nb.njit(cache=True)
def sense(world: WorldArrays) -> None:
    """The true readings at the world's poses (`World.sense`), into `world.readings`."""
    rays.ir_readings_grid(
        world.poses,
        world.wall_table,
        world.grid_frame,
        world.grid_starts,
        world.grid_members,
        world.readings,
    )


@nb.njit(cache=True)
def observe(world: WorldArrays, t: int) -> None:
    """What the controllers see at world step `t` (`World.observe`), into `world.observed`."""
    noise.observe(
        world.readings,
        world.keys,
        np.uint64(t),
        world.noise_sigma,
        world.fault_modes,
        world.stuck,
        world.observed,
        world.noise_stream,
    )


@nb.njit(cache=True, inline="always")
def read_lazily(
    observed: npt.NDArray[np.float64],
    source: tuple[WorldArrays, int, npt.NDArray[np.bool_]],
    i: int | np.uint64,
    j: int | np.uint64,
) -> float:
    """What robot i sees of sensor j at the step `source` = (world, t, drawn) names, drawn
    the first time a sensor of its pair is read in the step (`drawn`: (N, 4) bool, cleared each
    step): the value `observe` gives, computed only for the sensors a controller reads (a
    thesis-ch3 controller reads 1.1 of the 4 pairs a step)."""
    world, t, drawn = source
    i, b = int(i), int(j) >> 1
    if not drawn[i, b]:
        noise.observe_pair(
            world.readings,
            world.keys,
            np.uint64(t),
            world.noise_sigma,
            world.fault_modes,
            world.stuck,
            observed,
            i,
            b,
            world.noise_stream,
        )
        drawn[i, b] = True
    return observed[i, j]


@nb.njit(cache=True)
def step(world: WorldArrays, commands: np.ndarray) -> None:
    """One control period at wheel `commands` (`World.step` without its clock and faults)."""
    if not drive.clip_commands(commands, world.commands):
        raise ValueError("commands contain NaN")
    analytic.move(world.bodies, world.poses[:, 2], world.spins, world.commands)
    analytic.read_local_poses(world.bodies.state, world.bodies.offset, world.poses)
    drive.wheel_spins(world.commands, world.spins)


@nb.njit(cache=True)
def judge(readings: np.ndarray, commands: np.ndarray, out: np.ndarray) -> None:
    """Eq. 2.7's terms (`sim.reward_table` without its checks) into out (N, 4)."""
    reward.reward_kernel(readings, commands, out)


#: What this module's cached kernels were compiled against: sim/khepera.py's constants,
#: sim/faults.py's fault codes and the modules whose kernels it calls (sim.kernel_cache).
COMPILED_AGAINST = source_fingerprint(
    analytic, drive, faults, khepera, noise, rays, reward, sensors
)


@nb.njit(cache=True)
def _frozen_sources() -> np.ndarray:
    """``COMPILED_AGAINST`` as numba froze it into this module's cache."""
    return COMPILED_AGAINST.copy()


drop_stale_cache(globals(), _frozen_sources, COMPILED_AGAINST)
