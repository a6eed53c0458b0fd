"""The analytic physics against pymunk, its reference.

Conformance tolerance: none. The analytic world does chipmunk's arithmetic for a disc against
static frictionless segments operation by operation, in the same frame (a copy of the arena at
32768 mm or more, where every copy rounds alike), and solves a robot's contacts in the order
chipmunk's spatial hash finds them: poses agree bit for bit in free space, against one wall and
in corners. Measured: 0.0 mm over 300 robots × 1500 steps in each shipped arena, 17,805 to
42,518 of them touching two walls (docs/decisions.md). A pymunk release that changed chipmunk's
solver would fail these tests, which is the point: pymunk is the reference.
"""

import numpy as np
import pymunk
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from rooms import box
from test_world import corner_commands, held_commands, walls_touched

import sim
from sim.analytic import COLLISION_BIAS, COLLISION_PERSISTENCE, COLLISION_SLOP_MM
from sim.check import MAX_PENETRATION_MM
from sim.khepera import BODY_RADIUS_MM

TRAINING = sim.load_arena("training")
ROOM = box(600.0)


def tracks(
    arena: sim.Arena,
    poses: np.ndarray,
    commands: np.ndarray,
    sigma: float = 0.0,
    faults: tuple[sim.Fault, ...] = (),
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per physics: (steps, N, 3) poses after each step and (steps, N, 8) observations."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for physics in sim.PHYSICS:
        world = sim.World(arena, n=len(poses), seed=7, noise_sigma=sigma, physics=physics)
        world.reset(poses)
        world.schedule_faults(faults)
        track, seen = [], []
        for command in commands:
            seen.append(world.observe())
            world.step(command)
            track.append(world.poses)
        out[physics] = (np.array(track), np.array(seen))
    return out


def test_the_contact_constants_are_chipmunks_defaults() -> None:
    space = pymunk.Space()
    assert space.collision_slop == COLLISION_SLOP_MM
    assert space.collision_bias == COLLISION_BIAS
    assert space.collision_persistence == COLLISION_PERSISTENCE


def test_free_space_poses_are_identical_to_pymunk() -> None:
    n, steps = 40, 100
    rng = np.random.default_rng(1)
    poses = np.column_stack([np.full(n, 1000.0), np.full(n, 1000.0), rng.uniform(-4, 4, n)])
    # Held for 10 steps, some beyond the ±10 clip.
    commands = np.repeat(rng.uniform(-12, 12, (steps // 10, n, 2)), 10, axis=0)
    result = tracks(box(2000.0), poses, commands)
    pymunk_poses, analytic_poses = result["pymunk"][0], result["analytic"][0]
    assert np.all(box(2000.0).clearance(pymunk_poses[..., :2].reshape(-1, 2)) > BODY_RADIUS_MM)
    assert np.abs(pymunk_poses[-1, :, :2] - 1000.0).max() > 100  # they did move
    np.testing.assert_array_equal(analytic_poses, pymunk_poses)


def room_start(x: float, y: float, heading_deg: float) -> np.ndarray:
    return np.array([[x, y, np.deg2rad(heading_deg)]])


# One robot in a 600 mm square room, 100 steps each (the room's walls are at 0 and 600 mm).
WALL_SCENARIOS = {
    # Full speed straight into the wall at x = 600, then pressed on it.
    "head-on": (room_start(500, 300, 0), np.tile([10.0, 10.0], (100, 1))),
    # 30° into the wall, then sliding along it to the corner.
    "glancing": (room_start(450, 200, 30), np.tile([10.0, 10.0], (100, 1))),
    # Into the corner (600, 600) along the diagonal: pressed on two walls at once.
    "corner": (room_start(450, 450, 45), np.tile([10.0, 10.0], (100, 1))),
    # Pressed on the wall, then two steps forward and one back: contacts end and start again.
    "bouncing": (
        room_start(540, 300, 0),
        np.tile([[10.0, 10.0], [10.0, 10.0], [-3.0, -3.0]], (34, 1))[:100],
    ),
    # Turning on the spot while pressed on the wall, then curving away along it.
    "turning": (
        room_start(560, 300, 10),
        np.concatenate([np.tile([-6.0, 6.0], (50, 1)), np.tile([4.0, 10.0], (50, 1))]),
    ),
}


@pytest.mark.parametrize("scenario", WALL_SCENARIOS)
def test_along_and_into_walls_poses_are_identical_to_pymunk(scenario: str) -> None:
    start, commands = WALL_SCENARIOS[scenario]
    result = tracks(ROOM, start, commands[:, None, :])
    reference, analytic = result["pymunk"][0], result["analytic"][0]
    depth = BODY_RADIUS_MM - ROOM.clearance(reference[:, 0, :2])
    assert np.count_nonzero(depth > 0) >= 20  # the robot pressed on a wall for a while
    np.testing.assert_array_equal(analytic, reference)


@pytest.mark.parametrize("name", sim.ARENA_NAMES)
def test_many_robots_in_corners_are_identical_to_pymunk(name: str) -> None:
    """300 robots, 100 steps of turns held while driving forward: walls, slides and corners,
    convex ones around the obstacles included. These runs also meet chipmunk's rules that the
    scenarios above do not: the contacts' order in the spatial hash, and an impulse remembered
    for 3 substeps after its contact ends (making either rule naive fails this test)."""
    arena = sim.load_arena(name)
    n, steps = 300, 100
    rng = np.random.default_rng(5)
    poses = arena.start_poses[rng.integers(0, 10, n)]
    commands = np.stack(
        [corner_commands(np.random.default_rng([9, i]), steps, hold=10) for i in range(n)], axis=1
    )
    result = tracks(arena, poses, commands)
    reference, analytic = result["pymunk"][0], result["analytic"][0]
    touching = walls_touched(arena, reference[..., :2])
    assert np.count_nonzero(touching >= 1) > 1000
    assert np.count_nonzero(touching >= 2) > 50
    np.testing.assert_array_equal(analytic, reference)


def test_sensing_noise_and_faults_are_shared() -> None:
    """Same poses, so the same readings, noise draws and faults: observations agree too."""
    n, steps = 30, 120
    rng = np.random.default_rng(2)
    poses = TRAINING.start_poses[rng.integers(0, 10, n)]
    faults = (sim.Fault(40, (2, 3), "random"), sim.Fault(80, (0,), "stuck"))
    result = tracks(TRAINING, poses, held_commands(rng, steps, n), sigma=50.0, faults=faults)
    for a, b in zip(result["pymunk"], result["analytic"], strict=True):
        np.testing.assert_array_equal(a, b)


def test_robots_placed_mid_run_move_as_in_pymunk() -> None:
    """Placing a robot pressed on a wall forgets its velocity and contacts in both worlds."""
    n, steps = 40, 200
    rng = np.random.default_rng(8)
    poses = TRAINING.start_poses[rng.integers(0, 10, n)]
    commands = held_commands(rng, steps, n)
    again = TRAINING.start_poses[rng.integers(0, 10, n // 2)]
    out = {}
    for physics in sim.PHYSICS:
        world = sim.World(TRAINING, n=n, physics=physics)
        world.reset(poses)
        track = []
        for t, command in enumerate(commands):
            if t == steps // 2:
                pressed = BODY_RADIUS_MM - TRAINING.clearance(world.poses[: n // 2, :2]) > 0
                assert np.count_nonzero(pressed) >= 3
                world.place(again, robots=np.arange(n // 2))
            world.step(command)
            track.append(world.poses)
        out[physics] = np.array(track)
    np.testing.assert_array_equal(out["analytic"], out["pymunk"])


@settings(max_examples=30, deadline=None)
@given(
    arena=st.sampled_from(sim.ARENA_NAMES),
    start=st.integers(0, 9),
    commands=arrays(np.float64, (40, 2), elements=st.floats(-12, 12)),
    hold=st.integers(1, 20),
)
def test_robots_never_end_up_inside_walls(
    arena: str, start: int, commands: np.ndarray, hold: int
) -> None:
    room = sim.load_arena(arena)
    world = sim.World(room, n=1, physics="analytic")
    world.reset(room.start_poses[start : start + 1])
    for command in np.repeat(commands, hold, axis=0)[:300]:
        world.step(command[None])
        where = world.poses[:, :2]
        assert room.contains(where)[0]
        assert BODY_RADIUS_MM - room.clearance(where)[0] <= MAX_PENETRATION_MM


def test_an_analytic_robot_is_bit_identical_alone_and_in_a_batch() -> None:
    n, steps = 60, 200
    rng = np.random.default_rng(4)
    poses = TRAINING.start_poses[rng.integers(0, 10, n)]
    commands = np.stack(
        [held_commands(np.random.default_rng([4, i]), steps, 1)[:, 0] for i in range(n)], axis=1
    )

    def run(part: slice) -> np.ndarray:
        world = sim.World(TRAINING, n=len(poses[part]), physics="analytic")
        world.reset(poses[part])
        track = []
        for command in commands:
            world.step(command[part])
            track.append(world.poses)
        return np.array(track)

    batch = run(slice(0, n))
    for part in (slice(7, 8), slice(20, 60)):
        np.testing.assert_array_equal(run(part), batch[:, part])


def test_an_analytic_reset_forgets_velocities_and_contacts() -> None:
    n = 20
    rng = np.random.default_rng(6)
    poses = TRAINING.start_poses[rng.integers(0, 10, n)]
    used = sim.World(TRAINING, n=n, physics="analytic")
    used.reset(poses)
    for command in held_commands(rng, 150, n):  # ends moving, some robots pressed on walls
        used.step(command)
    assert np.any(BODY_RADIUS_MM - TRAINING.clearance(used.poses[:, :2]) > 0)
    fresh = sim.World(TRAINING, n=n, physics="analytic")
    used.reset(poses)
    fresh.reset(poses)
    for command in held_commands(rng, 100, n):
        used.step(command)
        fresh.step(command)
        np.testing.assert_array_equal(used.poses, fresh.poses)


def test_the_analytic_world_builds_no_pymunk_space(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_space() -> None:
        raise AssertionError("a pymunk space was built")

    monkeypatch.setattr(pymunk, "Space", no_space)
    world = sim.World(TRAINING, n=3, physics="analytic")
    world.step(np.full((3, 2), 10.0))
    assert world.poses[0, 0] != TRAINING.start_poses[0, 0]
    with pytest.raises(sim.WorldError, match="no pymunk space"):
        world.space_of(0)


def test_an_unknown_physics_is_a_world_error() -> None:
    with pytest.raises(sim.WorldError, match=r"unknown physics 'box2d'.*pymunk, analytic"):
        sim.World(TRAINING, n=1, physics="box2d")  # type: ignore[arg-type]
