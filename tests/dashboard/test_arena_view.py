"""The arena view draws each IR ray only as far as the wall it meets (rays used to cross walls)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import gnp
import sim
from app.brains.gnp_brain import GnpFamily
from app.phases.live import LiveSession, RobotSpec
from app.views import geometry as geo
from sim.sensors import ir_distances

ARENA = sim.load_arena("training")


def wall_distance(points: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """(P,) distance from each point (P, 2) to the nearest wall segment (K, 2, 2)."""
    p, e = walls[None, :, 0], walls[None, :, 1] - walls[None, :, 0]
    t = np.clip(np.einsum("pkj,pkj->pk", points[:, None] - p, e) / (e**2).sum(-1), 0.0, 1.0)
    return np.linalg.norm(points[:, None] - (p + t[..., None] * e), axis=-1).min(axis=1)


def crosses_a_wall(start: np.ndarray, end: np.ndarray, walls: np.ndarray) -> bool:
    """Whether the segment start→end passes through a wall (touching its end point aside)."""
    d = end - start
    p, e = walls[:, 0], walls[:, 1] - walls[:, 0]
    denom = d[0] * e[:, 1] - d[1] * e[:, 0]
    ok = np.abs(denom) > 1e-12
    w = p - start
    t = np.where(ok, (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / np.where(ok, denom, 1.0), -1.0)
    u = np.where(ok, (w[:, 0] * d[1] - w[:, 1] * d[0]) / np.where(ok, denom, 1.0), -1.0)
    return bool(np.any(ok & (t > 0.0) & (t < 1.0 - 1e-9) & (u >= 0.0) & (u <= 1.0)))


def test_a_distance_follows_from_a_reading_by_hand() -> None:
    readings = np.array([0.0, sim.IR_MAX, sim.IR_MAX / 2, 2 * sim.IR_MAX, -5.0])
    np.testing.assert_allclose(
        ir_distances(readings), [sim.IR_RANGE_MM, 0.0, sim.IR_RANGE_MM / 2, 0.0, sim.IR_RANGE_MM]
    )


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(0.0, 1.0),
    y=st.floats(0.0, 1.0),
    heading=st.floats(-np.pi, np.pi),
)
def test_a_ray_that_sees_a_wall_ends_on_it_and_crosses_none(
    x: float, y: float, heading: float
) -> None:
    xmin, ymin, xmax, ymax = ARENA.bounds
    pose = np.array([[xmin + x * (xmax - xmin), ymin + y * (ymax - ymin), heading]])
    readings = sim.ir_readings(pose, ARENA.wall_grid)[0]
    origins, directions = sim.sensor_rays(pose)
    reach = ir_distances(readings)
    ends = origins[0] + directions[0] * reach[:, None]
    hits = (readings > 0) & (reach > 0)  # reach 0: the wall is behind the sensor's origin
    np.testing.assert_allclose(wall_distance(ends[hits], ARENA.walls), 0.0, atol=1e-6)
    for start, end, reading in zip(origins[0], ends, readings, strict=True):
        if reading == 0:
            assert not crosses_a_wall(start, end, ARENA.walls)


@pytest.fixture(scope="module")
def server() -> Iterator[object]:
    import viser

    served = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield served
    served.stop()


def test_the_drawn_rays_stop_at_the_walls(server: object) -> None:
    """A robot beside a wall: the rays on the page end on it, the others are full length."""
    from app.views.arena_view import ArenaView

    cfg = gnp.GnpConfig(method="RL")
    session = LiveSession(
        ARENA,
        [RobotSpec("r", GnpFamily.of(cfg), gnp.init_population(cfg, 1, np.random.default_rng(0)))],
    )
    snapshot = session.snapshot()[0]
    view = ArenaView(server, ARENA, max_robots=1)  # type: ignore[arg-type]
    # Facing the left wall of the bounding box, 30 mm from it (closer than the range).
    xmin = ARENA.walls[..., 0].min()
    left = ARENA.walls[np.all(ARENA.walls[:, :, 0] == xmin, axis=1)][0]
    y = float(left[:, 1].mean())
    pose = np.array([xmin + sim.BODY_RADIUS_MM + 30.0, y, np.pi])
    true = sim.ir_readings(pose[None], ARENA.wall_grid)[0]
    assert (true > 0).any() and (true == 0).any()  # some rays see the wall, some nothing
    view.update((dataclasses.replace(snapshot, pose=pose, true_readings=true),))
    rays = view._robots[0]["rays"].points[:, :, :2] / geo.MM
    starts, ends = rays[:, 0].astype(np.float64), rays[:, 1].astype(np.float64)
    lengths = np.linalg.norm(ends - starts, axis=1)
    sees = true > 0
    # float32 on the page: a few micrometres of rounding at most.
    np.testing.assert_allclose(wall_distance(ends[sees], ARENA.walls), 0.0, atol=0.01)
    assert np.all(lengths[sees] < sim.IR_RANGE_MM)
    np.testing.assert_allclose(lengths[~sees], sim.IR_RANGE_MM, rtol=1e-5)
    for start, end in zip(starts[~sees], ends[~sees], strict=True):
        assert not crosses_a_wall(start, end, ARENA.walls)


def test_the_frame_holds_every_arena_with_the_graph_below(server: object) -> None:
    """Bounds in mm → scene metres, by hand: x −0.1..1.0, y 0..0.8, so the width is 1.1."""
    from types import SimpleNamespace

    from app.views.scene import aim_camera, scene_frame

    arenas = [
        SimpleNamespace(bounds=(0, 0, 1000, 500)),
        SimpleNamespace(bounds=(-100, 0, 900, 800)),
    ]
    frame = scene_frame(arenas)  # type: ignore[arg-type]
    assert (frame.xmin, frame.xmax, frame.ymax) == pytest.approx((-0.1, 1.0, 0.8))
    assert frame.width == pytest.approx(1.1) and frame.graph_height == pytest.approx(0.682)
    assert frame.graph_origin == pytest.approx((-0.1, -0.12 * 1.1 - 0.682))
    aim_camera(server, frame, headroom=0.03)  # type: ignore[arg-type]
    camera = server.initial_camera  # type: ignore[attr-defined]
    bottom, top = -0.814 - 0.05 * 1.1, 0.8 + 0.03 * 1.1
    assert tuple(camera.look_at) == pytest.approx((0.45, (bottom + top) / 2, 0.0))
    distance = 1.08 * (top - bottom) / 2 / np.tan(np.radians(50.0) / 2)
    assert tuple(camera.position) == pytest.approx((0.45, (bottom + top) / 2, distance))
