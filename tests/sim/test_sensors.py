"""IR sensors: the reading model, the pymunk oracle, and invariants."""

import numpy as np
import pymunk
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rooms import box

import sim
from sim import rays
from sim.khepera import (
    BODY_RADIUS_MM,
    IR_BACKOFF_MM,
    IR_MAX,
    IR_RANGE_MM,
    SENSOR_HEADINGS_RAD,
    SENSOR_ORIGINS_MM,
)
from sim.spaces import RAY_FILTER


def expected(d: float) -> float:
    return IR_MAX * max(0.0, 1.0 - d / IR_RANGE_MM)


@pytest.mark.parametrize("d", [1.5, 2.0, 5.0, 12.5, 25.0, 37.0, 49.0, 49.9, 50.0, 50.1, 60.0])
def test_front_sensors_read_the_distance_to_a_straight_wall(d: float) -> None:
    world = sim.World(box(1000.0), n=1)
    front_x = SENSOR_ORIGINS_MM[2, 0]  # s2 and s3 sit 27.5 mm ahead of the centre, facing 0°
    world.reset(np.array([[1000.0 - front_x - d, 500.0, 0.0]]))
    readings = world.sense()[0]
    assert readings[2] == pytest.approx(expected(d), abs=1.0)
    assert readings[3] == pytest.approx(expected(d), abs=1.0)
    if d >= 50:
        assert readings[2] == readings[3] == 0.0


def test_sensors_pointing_away_from_every_wall_read_zero() -> None:
    world = sim.World(box(1000.0), n=2)
    world.reset(np.array([[500.0, 500.0, 0.3], [1000.0 - 27.5 - 10.0, 500.0, 0.0]]))
    readings = world.sense()
    assert np.all(readings[0] == 0.0)  # in the middle of the room: nothing in reach
    assert readings[1, 2] > 700 and np.all(readings[1, [6, 7]] == 0.0)  # rear sensors face away


def test_side_sensor_reads_a_wall_along_its_slanted_ray() -> None:
    world = sim.World(box(1000.0), n=1)
    world.reset(np.array([[500.0, 50.0, 0.0]]))  # 50 mm above the floor wall, facing +x
    readings = world.sense()[0]
    # s5 at (12.1, -25.8) looks at -85°: it meets y = 0 after (50 - 25.8) / sin 85°.
    assert readings[5] == pytest.approx(expected(24.2 / np.sin(np.deg2rad(85))), abs=1e-9)
    # s4 at (21.4, -18.9) looks at -45°.
    assert readings[4] == pytest.approx(expected(31.1 / np.sin(np.deg2rad(45))), abs=1e-9)
    assert np.all(readings[[0, 1, 2, 3, 6, 7]] == 0.0)


@pytest.mark.parametrize("approach_deg", [0.0, 20.0, 40.0, 60.0])
def test_a_robot_pressing_on_a_wall_reads_at_least_1000(approach_deg: float) -> None:
    world = sim.World(box(1000.0), n=1)
    # Face the east wall at an angle, then drive straight into it for 3 s.
    world.reset(np.array([[900.0, 500.0, np.deg2rad(approach_deg)]]))
    for _ in range(50):
        world.step(np.array([[10.0, 10.0]]))
    readings = world.sense()
    assert world.poses[0, 0] > 1000 - BODY_RADIUS_MM - 2.0  # it is touching the wall
    assert readings.max() >= 1000
    assert sim.reward_terms(readings, np.array([[10.0, 10.0]]))["reward/near_wall"][0] == 0.0


def pymunk_readings(world: sim.World) -> np.ndarray:
    """The oracle: pymunk's own segment_query_first on the robots' copies of the arena."""
    origins, directions = sim.sensor_rays(world.poses)
    out = np.zeros((world.n, 8))
    for i in range(world.n):
        space, offset = world.space_of(i)
        for j in range(8):
            start = origins[i, j] + offset - IR_BACKOFF_MM * directions[i, j]
            end = origins[i, j] + offset + IR_RANGE_MM * directions[i, j]
            hit = space.segment_query_first(tuple(start), tuple(end), 0.0, RAY_FILTER)
            if hit is not None:
                assert isinstance(hit.shape, pymunk.Segment)
                d = max(0.0, hit.alpha * (IR_RANGE_MM + IR_BACKOFF_MM) - IR_BACKOFF_MM)
                out[i, j] = expected(d)
    return out


@pytest.mark.parametrize("name", sim.ARENA_NAMES)
def test_ray_casting_agrees_with_pymunk_segment_queries(name: str) -> None:
    arena = sim.load_arena(name)
    rng = np.random.default_rng(7)
    # Thousands of random poses, most of them near walls so that rays hit something.
    xmin, ymin, xmax, ymax = arena.bounds
    candidates = rng.uniform([xmin, ymin, -np.pi], [xmax, ymax, np.pi], (40_000, 3))
    clearance = arena.clearance(candidates[:, :2])
    free = arena.contains(candidates[:, :2]) & (clearance > BODY_RADIUS_MM)
    poses = candidates[free & (clearance < BODY_RADIUS_MM + IR_RANGE_MM)][:1500]
    assert len(poses) == 1500
    world = sim.World(arena, n=len(poses))
    world.reset(poses)
    ours = world.sense()
    oracle = pymunk_readings(world)
    assert np.count_nonzero(oracle) > 2000  # the test exercises hits, not just misses
    np.testing.assert_allclose(ours, oracle, rtol=0, atol=1e-6)


def test_sensor_rays_follow_the_khepera_layout() -> None:
    poses = np.array([[100.0, 200.0, 0.0], [0.0, 0.0, np.pi / 2]])
    origins, directions = sim.sensor_rays(poses)
    assert origins.shape == directions.shape == (2, 8, 2)
    np.testing.assert_allclose(origins[0], SENSOR_ORIGINS_MM + np.array([100.0, 200.0]))
    np.testing.assert_allclose(origins[1], SENSOR_ORIGINS_MM @ [[0, 1], [-1, 0]], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0)
    headings = np.arctan2(directions[0, :, 1], directions[0, :, 0])
    np.testing.assert_allclose(np.exp(1j * headings), np.exp(1j * SENSOR_HEADINGS_RAD))
    # Every sensor sits on the body's surface (Webots' positions moved along the ray).
    np.testing.assert_allclose(np.linalg.norm(SENSOR_ORIGINS_MM, axis=1), BODY_RADIUS_MM, atol=0.1)


TRAINING = sim.load_arena("training")


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-200, 1200),
    y=st.floats(-200, 1000),
    heading=st.floats(-10, 10),
)
def test_readings_are_always_within_0_and_1023(x: float, y: float, heading: float) -> None:
    """Any pose at all, even overlapping or outside walls: readings stay in range."""
    out = np.full((1, 8), np.nan)
    rays.ir_readings(np.array([[x, y, heading]]), rays.wall_table(TRAINING.walls), out)
    assert np.all((out >= 0) & (out <= IR_MAX))


@settings(max_examples=100, deadline=None)
@given(index=st.integers(0, 9), turns=st.integers(-3, 3))
def test_readings_do_not_depend_on_whole_turns_of_the_heading(index: int, turns: int) -> None:
    pose = TRAINING.start_poses[index].copy()
    table = rays.wall_table(TRAINING.walls)
    a, b = np.zeros((1, 8)), np.zeros((1, 8))
    rays.ir_readings(pose[None], table, a)
    pose[2] += 2 * np.pi * turns
    rays.ir_readings(pose[None], table, b)
    np.testing.assert_allclose(a, b, atol=1e-6)
