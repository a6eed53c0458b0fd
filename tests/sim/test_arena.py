"""Arena loading: the shipped arenas and one error per kind of broken arena file."""

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sim
from sim.arena import point_segment_distance
from sim.khepera import BODY_RADIUS_MM

CORRIDOR_MM = 150.0


def square_room(**changes: Any) -> dict[str, Any]:
    """A valid 600 × 600 mm room with one pillar and one wall stub, as JSON data."""
    room: dict[str, Any] = {
        "name": "room",
        "outer_wall": [[0, 0], [600, 0], [600, 600], [0, 600], [0, 0]],
        "obstacles": [
            {"name": "pillar", "shape": "polygon", "points": [[250, 250], [350, 250], [300, 350]]},
            {"name": "stub", "shape": "polyline", "points": [[100, 450], [200, 450]]},
        ],
        "start_poses": [
            {"name": f"p{i}", "x": 50 + 50 * i, "y": 50, "heading_deg": 0} for i in range(10)
        ],
    }
    room.update(changes)
    return room


def write(tmp_path: Path, data: Any) -> Path:
    path = tmp_path / "arena.json"
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def load_error(tmp_path: Path, data: Any) -> str:
    with pytest.raises(sim.ArenaError) as err:
        sim.load_arena(write(tmp_path, data))
    return str(err.value)


@pytest.mark.parametrize("name", sim.ARENA_NAMES)
def test_shipped_arena_loads_with_ten_wall_following_starts(name: str) -> None:
    arena = sim.load_arena(name)
    assert arena.name == name
    assert arena.start_poses.shape == (10, 3)
    assert len(set(arena.start_names)) == 10
    xmin, ymin, xmax, ymax = arena.bounds
    assert 800 <= max(xmax - xmin, ymax - ymin) <= 1200  # Khepera scale, about 1 m across
    points = arena.start_poses[:, :2]
    assert np.all(arena.contains(points))
    # Near a wall (a sensor sees it) but clear of it by more than a few millimetres ...
    clearance = arena.clearance(points)
    assert np.all(clearance >= BODY_RADIUS_MM + 5)
    assert np.all(clearance <= BODY_RADIUS_MM + sim.IR_RANGE_MM)
    # ... and facing along it.
    distances = point_segment_distance(points, arena.walls)
    nearest = arena.walls[np.argmin(distances, axis=1)]
    along = nearest[:, 1] - nearest[:, 0]
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    heading = np.column_stack([np.cos(arena.start_poses[:, 2]), np.sin(arena.start_poses[:, 2])])
    assert np.all(np.abs(np.sum(along * heading, axis=1)) > 0.999)


def closest_points(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest points of segments a and b (2, 2) (they do not cross)."""
    candidates = []
    for p, seg in ((a[0], b), (a[1], b), (b[0], a), (b[1], a)):
        e = seg[1] - seg[0]
        t = np.clip(np.dot(p - seg[0], e) / np.dot(e, e), 0, 1)
        q = seg[0] + t * e
        candidates.append((np.linalg.norm(p - q), p, q))
    _, p, q = min(candidates, key=lambda c: c[0])
    return p, q


@pytest.mark.parametrize("name", sim.ARENA_NAMES)
def test_shipped_arena_corridors_are_wide_enough_to_follow_every_wall(name: str) -> None:
    """Wherever two walls face each other across free space, they are ≥ 150 mm apart."""
    arena = sim.load_arena(name)
    walls = arena.walls
    for i in range(len(walls)):
        for j in range(i + 1, len(walls)):
            p, q = closest_points(walls[i], walls[j])
            gap = float(np.linalg.norm(p - q))
            if gap < 1e-9:
                continue  # neighbours meeting at a corner
            across = (p + q) / 2
            if arena.contains(across) and arena.clearance(across) > 1e-6:
                assert gap >= CORRIDOR_MM, f"walls {i} and {j} are {gap:.0f} mm apart"


def test_the_two_arenas_differ() -> None:
    training, implementation = sim.load_arena("training"), sim.load_arena("implementation")
    assert training.walls.shape != implementation.walls.shape or not np.allclose(
        training.walls, implementation.walls
    )


def test_a_valid_file_loads_with_polylines_and_polygons(tmp_path: Path) -> None:
    arena = sim.load_arena(write(tmp_path, square_room()))
    assert arena.walls.shape == (4 + 3 + 1, 2, 2)
    assert len(arena.solids) == 1
    assert arena.bounds == (0.0, 0.0, 600.0, 600.0)
    assert np.allclose(arena.start_poses[3], [200, 50, 0])
    assert not arena.contains(np.array([300.0, 280.0]))  # inside the pillar
    assert arena.contains(np.array([150.0, 450.0]))  # on no solid: a stub has no inside
    with pytest.raises(ValueError):
        arena.walls[0, 0, 0] = 1.0  # arrays are read-only


def test_unknown_name_lists_the_shipped_arenas() -> None:
    with pytest.raises(sim.ArenaError, match=r"unknown arena 'nowhere'.*implementation, training"):
        sim.load_arena("nowhere")


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(sim.ArenaError, match="arena file not found"):
        sim.load_arena(tmp_path / "absent.json")


def test_bad_json(tmp_path: Path) -> None:
    assert "not valid JSON" in load_error(tmp_path, '{"name": "x", ')


def test_unknown_field(tmp_path: Path) -> None:
    message = load_error(tmp_path, square_room(colour="red"))
    assert "colour" in message and "Extra inputs are not permitted" in message


def test_unknown_field_in_a_start_pose(tmp_path: Path) -> None:
    room = square_room()
    room["start_poses"][2]["speed"] = 3
    assert "start_poses.2.speed" in load_error(tmp_path, room)


def test_missing_field(tmp_path: Path) -> None:
    room = square_room()
    del room["outer_wall"]
    assert "outer_wall: Field required" in load_error(tmp_path, room)


def test_wrong_number_of_start_poses(tmp_path: Path) -> None:
    room = square_room()
    room["start_poses"] = room["start_poses"][:9]
    assert "start_poses" in load_error(tmp_path, room)


def test_open_outer_wall(tmp_path: Path) -> None:
    message = load_error(tmp_path, square_room(outer_wall=[[0, 0], [600, 0], [600, 600], [0, 600]]))
    assert "outer_wall is not closed" in message and str(tmp_path) in message


def test_self_intersecting_outer_wall(tmp_path: Path) -> None:
    bowtie = [[0, 0], [600, 600], [600, 0], [0, 600], [0, 0]]
    assert "outer_wall is self-intersecting" in load_error(tmp_path, square_room(outer_wall=bowtie))


def test_outer_wall_folding_back_on_itself(tmp_path: Path) -> None:
    folded = [[0, 0], [600, 0], [300, 0], [300, 600], [0, 600], [0, 0]]
    assert "self-intersecting" in load_error(tmp_path, square_room(outer_wall=folded))


def test_repeated_point(tmp_path: Path) -> None:
    repeated = [[0, 0], [600, 0], [600, 0], [600, 600], [0, 600], [0, 0]]
    assert "zero length" in load_error(tmp_path, square_room(outer_wall=repeated))


def test_self_intersecting_obstacle(tmp_path: Path) -> None:
    room = square_room()
    room["obstacles"][0]["points"] = [[250, 250], [350, 350], [350, 250], [250, 350]]
    message = load_error(tmp_path, room)
    assert "obstacles[0] ('pillar')" in message and "self-intersecting" in message


def test_obstacle_outside_the_outer_wall(tmp_path: Path) -> None:
    room = square_room()
    room["obstacles"][1]["points"] = [[500, 450], [700, 450]]
    assert "obstacles[1] ('stub')" in load_error(tmp_path, room)


def test_start_pose_outside_the_outer_wall(tmp_path: Path) -> None:
    room = square_room()
    room["start_poses"][4].update(x=-100, y=300)
    message = load_error(tmp_path, room)
    assert "start_poses[4] ('p4')" in message and "outside the outer wall" in message


def test_start_pose_inside_an_obstacle(tmp_path: Path) -> None:
    room = square_room()
    room["start_poses"][7].update(x=300, y=280)
    message = load_error(tmp_path, room)
    assert "start_poses[7] ('p7')" in message and "inside an obstacle" in message


def test_start_pose_within_a_body_radius_of_a_wall(tmp_path: Path) -> None:
    room = square_room()
    room["start_poses"][0].update(x=300, y=20)
    message = load_error(tmp_path, room)
    assert "start_poses[0] ('p0')" in message and "20.0 mm from a wall" in message


def test_start_pose_names_repeat(tmp_path: Path) -> None:
    room = square_room()
    room["start_poses"][1]["name"] = "p0"
    assert "start pose names repeat" in load_error(tmp_path, room)


def test_non_finite_coordinate(tmp_path: Path) -> None:
    room = square_room()
    room["start_poses"][1]["x"] = float("nan")
    assert "start_poses.1.x" in load_error(tmp_path, json.dumps(room))


def test_arena_too_large_for_its_copies(tmp_path: Path) -> None:
    huge = [[0, 0], [5000, 0], [5000, 600], [0, 600], [0, 0]]
    assert "more than the" in load_error(tmp_path, square_room(outer_wall=huge))


coordinate = st.floats(-100, 1100, allow_nan=False)
point = st.tuples(coordinate, coordinate)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    outer=st.lists(point, min_size=3, max_size=8),
    close=st.booleans(),
    obstacle=st.lists(point, min_size=2, max_size=5),
    shape=st.sampled_from(["polygon", "polyline"]),
    starts=st.lists(point, min_size=10, max_size=10),
)
def test_any_arena_file_loads_or_fails_with_an_arena_error(
    tmp_path_factory: pytest.TempPathFactory,
    outer: list[tuple[float, float]],
    close: bool,
    obstacle: list[tuple[float, float]],
    shape: str,
    starts: list[tuple[float, float]],
) -> None:
    """Whatever the geometry, loading never crashes deep inside: it works or names a problem."""
    room = square_room(
        outer_wall=[*outer, outer[0]] if close else outer,
        obstacles=[{"name": "thing", "shape": shape, "points": obstacle}],
        start_poses=[
            {"name": f"p{i}", "x": x, "y": y, "heading_deg": 0} for i, (x, y) in enumerate(starts)
        ],
    )
    path = write(tmp_path_factory.mktemp("fuzz"), room)
    try:
        arena = sim.load_arena(path)
    except sim.ArenaError as err:
        assert str(path) in str(err)
    else:
        assert np.all(arena.contains(arena.start_poses[:, :2]))
        assert np.all(arena.clearance(arena.start_poses[:, :2]) > BODY_RADIUS_MM)
