"""The culled ray casts (``ir_readings_grid``) equal the reference kernel to the bit.

``sim.rays.ir_readings`` is the kernel as it was before the cull (it tests every wall for
reach); every reading the world produces now comes from ``ir_readings_grid``. They must agree
bit for bit on any pose: inside and outside the arenas, off the grid, on random wall sets, and
with a wall at exactly the reach distance (and one float either side of it).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import sim
from sim import rays
from sim.sensors import WallGrid, ir_readings, wall_grid

ARENAS = {name: sim.load_arena(name) for name in sim.ARENA_NAMES}


def reference(poses: np.ndarray, grid: WallGrid) -> np.ndarray:
    out = np.full((len(poses), sim.N_SENSORS), np.nan)
    rays.ir_readings(np.ascontiguousarray(poses), grid.table, out)
    return out


def assert_same_bits(a: np.ndarray, b: np.ndarray) -> None:
    assert a.shape == b.shape
    assert np.array_equal(a.view(np.uint64), b.view(np.uint64))


def at_reach(walls: np.ndarray, rng: np.random.Generator, per_wall: int) -> np.ndarray:
    """Poses whose centre is REACH_MM from a wall (perpendicular to an inner point, or from an
    end point), and one float nearer and farther, with random headings."""
    out = []
    for a, b in walls:
        e = b - a
        normal = np.array([-e[1], e[0]]) / np.hypot(*e)
        for _ in range(per_wall):
            side = rng.choice([-1.0, 1.0])
            inner = a + rng.uniform(0.01, 0.99) * e + side * rays.REACH_MM * normal
            angle = rng.uniform(0, 2 * np.pi)
            corner = a + rays.REACH_MM * np.array([np.cos(angle), np.sin(angle)])
            for centre in (inner, corner):
                for x in (
                    np.nextafter(centre[0], -np.inf),
                    centre[0],
                    np.nextafter(centre[0], np.inf),
                ):
                    out.append([x, centre[1], rng.uniform(-np.pi, np.pi)])
    return np.array(out)


@pytest.mark.parametrize("name", sim.ARENA_NAMES)
def test_grid_readings_equal_the_reference_on_many_poses(name: str) -> None:
    arena = ARENAS[name]
    grid = arena.wall_grid
    rng = np.random.default_rng(19)
    xmin, ymin, xmax, ymax = arena.bounds
    uniform = np.column_stack(
        [
            rng.uniform(xmin - 150, xmax + 150, 20_000),  # past the grid's edge too
            rng.uniform(ymin - 150, ymax + 150, 20_000),
            rng.uniform(-20, 20, 20_000),
        ]
    )
    poses = np.concatenate([uniform, at_reach(arena.walls, rng, 20)])
    expected = reference(poses, grid)
    assert np.count_nonzero(expected) > 10_000  # many rays do hit walls
    assert_same_bits(ir_readings(poses, grid), expected)


def test_a_wall_at_exactly_the_reach_is_listed_and_read_alike() -> None:
    # A horizontal wall REACH_MM above the robot's centre, on a cell corner and a cell centre.
    for x in (0.0, 10.0):
        walls = np.array([[[-500.0, rays.REACH_MM], [500.0, rays.REACH_MM]]])
        grid = wall_grid(walls)
        for y in (0.0, np.nextafter(0.0, 1.0), np.nextafter(0.0, -1.0)):
            heading = np.linspace(-np.pi, np.pi, 64)
            poses = np.column_stack([np.full(64, x), np.full(64, y), heading])
            assert_same_bits(ir_readings(poses, grid), reference(poses, grid))


@settings(max_examples=60, deadline=None)
@given(
    walls=arrays(np.float64, (5, 2, 2), elements=st.floats(0, 400)),
    poses=arrays(np.float64, (40, 3), elements=st.floats(-100, 500)),
    cell=st.sampled_from([1.0, 7.5, 20.0, 100.0, 1000.0]),
)
def test_grid_readings_equal_the_reference_for_any_walls(
    walls: np.ndarray, poses: np.ndarray, cell: float
) -> None:
    walls = walls[np.hypot(*(walls[:, 1] - walls[:, 0]).T) > 1e-3]  # no zero-length wall
    if len(walls) == 0:
        return
    grid = wall_grid(walls, cell)
    assert_same_bits(ir_readings(poses, grid), reference(poses, grid))


@pytest.mark.parametrize("name", sim.ARENA_NAMES)
def test_every_cell_lists_every_wall_within_reach_of_its_points(name: str) -> None:
    grid = ARENAS[name].wall_grid
    x0, y0, side, cols, rows = grid.frame
    rng = np.random.default_rng(5)
    cells = rng.integers(0, int(cols * rows), 3000)
    col, row = cells % int(cols), cells // int(cols)
    points = np.column_stack(
        [x0 + (col + rng.random(len(cells))) * side, y0 + (row + rng.random(len(cells))) * side]
    )
    gaps = np.empty((len(grid.table), len(points)))
    for w in range(len(grid.table)):
        rays.wall_distances(points, grid.table[w : w + 1], gaps[w])
    for k, cell in enumerate(cells):
        listed = set(grid.members[grid.starts[cell] : grid.starts[cell + 1]].tolist())
        assert set(np.flatnonzero(gaps[:, k] <= rays.REACH_MM).tolist()) <= listed
    assert np.diff(grid.starts).mean() < 0.2 * len(grid.table)  # and the cull is worth it


def test_the_world_senses_through_the_grid() -> None:
    arena = ARENAS["training"]
    world = sim.World(arena, n=10)
    world.step(np.tile([5.0, 4.0], (10, 1)))
    # the world's own unwrapped poses: `world.poses` wraps the heading, which moves its bits
    assert_same_bits(world.sense(), reference(world._poses, arena.wall_grid))
    with pytest.raises(ValueError, match="shape"):
        ir_readings(np.zeros((3, 2)), arena.wall_grid)
