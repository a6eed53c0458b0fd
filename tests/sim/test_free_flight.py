"""The analytic physics' free flight (a robot far from every wall skips the contact search) moves
no bit: worlds stepped with it and with every robot forced through the search hold equal arrays.

Compared after every step: the bodies' whole state (poses, velocities, bias velocities), their
substep stamps and their memory of contacts (walls, impulses, stamps). Robots drive in the
training arena, into walls and corners and away again (remembered contacts forgotten in flight),
and single robots start at random states near a wall of a small room (hypothesis).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from rooms import box
from test_world import corner_commands, held_commands

import sim
from sim import analytic
from sim.analytic import AnalyticBodies
from sim.khepera import BODY_RADIUS_MM

TRAINING = sim.load_arena("training")
ROOM = box(400.0)


def _world(arena: sim.Arena, poses: np.ndarray, free_flight: bool) -> sim.World:
    world = sim.World(arena, n=len(poses), seed=3, physics="analytic")
    world.reset(poses)
    bodies = world._analytic
    assert bodies is not None
    bodies.free_flight = free_flight
    return world


def _bodies(world: sim.World) -> AnalyticBodies:
    assert world._analytic is not None
    return world._analytic


def _assert_same(a: AnalyticBodies, b: AnalyticBodies) -> None:
    for name in ("state", "stamps", "seen_wall", "seen_impulse", "seen_stamp"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def _flying(world: sim.World) -> np.ndarray:
    """(N,) whether each robot surely flies free in the world's next step: its nearest wall
    beyond its radius, the most a full-speed period moves it, the margin and slack for the
    velocity it carries (the test only needs to see both kinds of robot)."""
    return TRAINING.clearance(world.poses[:, :2]) > BODY_RADIUS_MM + 4.8 + 1.0 + 5.0


def test_free_flight_is_the_contact_search_to_the_bit() -> None:
    n, steps = 60, 400
    rng = np.random.default_rng(11)
    poses = TRAINING.start_poses[rng.integers(0, 10, n)]
    commands = held_commands(rng, steps, n)
    commands[:, : n // 3] = np.stack(
        [corner_commands(np.random.default_rng([11, i]), steps) for i in range(n // 3)], axis=1
    )  # a third pressed into corners: two walls remembered, then forgotten on the way out
    commands[steps // 2 :, : n // 3] *= -1.0
    fast, slow = _world(TRAINING, poses, True), _world(TRAINING, poses, False)
    flying = np.zeros(n, dtype=np.int64)
    for command in commands:
        flying += _flying(fast)
        fast.step(command)
        slow.step(command)
        _assert_same(_bodies(fast), _bodies(slow))
        assert np.array_equal(fast.poses, slow.poses)
    assert flying.sum() > n * steps // 4  # many robot-steps flew
    assert flying.sum() < n * steps - n * steps // 10  # and many touched or neared a wall
    assert np.any(_bodies(slow).seen_stamp > 0)  # contacts were remembered


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(29.0, 371.0),
    y=st.floats(29.0, 371.0),
    heading=st.floats(-4.0, 4.0),
    velocity=st.lists(st.floats(-200.0, 200.0), min_size=6, max_size=6),
    memory=st.lists(st.tuples(st.integers(-1, 3), st.floats(0.0, 5e4), st.integers(0, 6)),
                    min_size=analytic.MAX_REMEMBERED, max_size=analytic.MAX_REMEMBERED),
    stamp=st.integers(0, 6),
    commands=st.lists(st.tuples(st.floats(-12.0, 12.0), st.floats(-12.0, 12.0)),
                      min_size=1, max_size=4),
)  # fmt: skip
def test_any_robot_near_a_wall_moves_alike_with_and_without_free_flight(
    x: float,
    y: float,
    heading: float,
    velocity: list[float],
    memory: list[tuple[int, float, int]],
    stamp: int,
    commands: list[tuple[float, float]],
) -> None:
    pose = np.array([[x, y, heading]])
    worlds = [_world(ROOM, pose, free_flight) for free_flight in (True, False)]
    for world in worlds:  # any velocity, bias velocity and memory of contacts to start from
        bodies = _bodies(world)
        bodies.state[0, 3:] = velocity
        bodies.stamps[0] = stamp
        bodies.seen_wall[0] = [wall for wall, _, _ in memory]
        bodies.seen_impulse[0] = [impulse for _, impulse, _ in memory]
        bodies.seen_stamp[0] = [seen for _, _, seen in memory]
    for command in commands:
        for world in worlds:
            world.step(np.array([command]))
        _assert_same(*(_bodies(world) for world in worlds))
