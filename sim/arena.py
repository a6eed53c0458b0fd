"""Arenas: walls and start poses, loaded from JSON and validated."""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from sim.khepera import BODY_RADIUS_MM

if TYPE_CHECKING:
    from sim.sensors import WallGrid

ARENA_NAMES: tuple[str, ...] = ("implementation", "training")
N_START_POSES = 10
MAX_EXTENT_MM = 3000.0
"""Largest arena side: each robot gets its own copy of the arena in a space (see ``sim.spaces``)."""
_EPS = 1e-9
# Bounds on an arena's size: its checks are quadratic in its segments, and an arena can come
# inline from a run file someone sent.
MAX_POINTS = 1000
MAX_OBSTACLES = 100
MAX_COORDINATE_MM = 1e6
"""Largest |coordinate| of a point or start pose (and |heading|, in degrees): far beyond any
arena (``MAX_EXTENT_MM``), and small enough that the geometry's products cannot overflow."""


class ArenaError(ValueError):
    """An arena file is missing, malformed or geometrically invalid."""


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE_MM, le=MAX_COORDINATE_MM)]
Point = tuple[Coordinate, Coordinate]


class StartPoseSpec(_Spec):
    name: str = Field(min_length=1)
    x: Coordinate
    y: Coordinate
    heading_deg: Coordinate


class ObstacleSpec(_Spec):
    name: str = Field(min_length=1)
    shape: Literal["polygon", "polyline"]
    points: list[Point] = Field(min_length=2, max_length=MAX_POINTS)


class ArenaSpec(_Spec):
    """The JSON schema of an arena file (millimetres, degrees)."""

    name: str = Field(min_length=1)
    description: str = ""
    outer_wall: list[Point] = Field(min_length=4, max_length=MAX_POINTS)
    """A closed polyline: the last point repeats the first."""
    obstacles: list[ObstacleSpec] = Field(default=[], max_length=MAX_OBSTACLES)
    start_poses: list[StartPoseSpec] = Field(min_length=N_START_POSES, max_length=N_START_POSES)


@dataclass(frozen=True, eq=False)
class Arena:
    """A validated arena. Coordinates are arena-local millimetres, headings radians.

    Attributes:
        name: The arena's name.
        walls: (K, 2, 2) wall segments.
        start_poses: (10, 3) start poses: x, y, heading.
        start_names: The 10 start poses' names.
        bounds: (xmin, ymin, xmax, ymax) of the outer wall.
        outer: (M, 2) outer wall polygon (not repeating its first vertex).
        solids: Polygon obstacles (each (M, 2)); robots may not be inside them.
        description: Free text from the file.
    """

    name: str
    walls: np.ndarray
    start_poses: np.ndarray
    start_names: tuple[str, ...]
    bounds: tuple[float, float, float, float]
    outer: np.ndarray
    solids: tuple[np.ndarray, ...]
    description: str = ""

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Whether points (..., 2) lie in free space: inside the outer wall, outside solids."""
        from sim import rays  # numba's kernels: imported when an arena is used, not defined

        flat = _as_points(points)
        inside = np.empty(len(flat), dtype=bool)
        rays.in_polygon(flat, np.ascontiguousarray(self.outer), inside)
        in_solid = np.empty(len(flat), dtype=bool)
        for solid in self.solids:
            rays.in_polygon(flat, np.ascontiguousarray(solid), in_solid)
            inside &= ~in_solid
        return inside.reshape(np.shape(points)[:-1])

    def clearance(self, points: np.ndarray) -> np.ndarray:
        """Distance (...,) from points (..., 2) to the nearest wall, mm."""
        from sim import rays

        flat = _as_points(points)
        out = np.empty(len(flat))
        rays.wall_distances(flat, self.wall_table, out)
        return out.reshape(np.shape(points)[:-1])

    @cached_property
    def wall_table(self) -> np.ndarray:
        """The walls as ``sim.rays.wall_table`` rows, for the numba kernels."""
        from sim import rays

        return rays.wall_table(self.walls)

    @cached_property
    def wall_grid(self) -> WallGrid:
        """The walls near each cell, for ``sim.sensors.ir_readings`` (built once per arena)."""
        from sim.sensors import wall_grid

        return wall_grid(self.walls)


def _as_points(points: np.ndarray) -> np.ndarray:
    flat = np.ascontiguousarray(points, dtype=np.float64)
    if flat.shape[-1:] != (2,):
        raise ValueError(f"points must have shape (..., 2), got {flat.shape}")
    return flat.reshape(-1, 2)


def load_arena(name_or_path: str | Path) -> Arena:
    """Load and validate an arena.

    Args:
        name_or_path: A shipped arena's name (see ``ARENA_NAMES``) or a path to a JSON file.

    Raises:
        ArenaError: naming the file and the problem.
    """
    text, source = _read(name_or_path)
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as err:
        raise ArenaError(f"{source}: not valid JSON: {err}") from None
    except RecursionError:
        raise ArenaError(f"{source}: JSON nested too deep") from None
    try:
        spec = ArenaSpec.model_validate(raw)
    except ValidationError as err:
        problems = "; ".join(
            f"{'.'.join(str(part) for part in e['loc']) or '(top level)'}: {e['msg']}"
            for e in err.errors()
        )
        raise ArenaError(f"{source}: invalid arena: {problems}") from None
    return arena_from_spec(spec, source)


def _read(name_or_path: str | Path) -> tuple[str, str]:
    as_text = str(name_or_path)
    looks_like_path = isinstance(name_or_path, Path) or as_text.endswith(".json") or "/" in as_text
    if not looks_like_path:
        if as_text not in ARENA_NAMES:
            raise ArenaError(
                f"unknown arena {as_text!r}: shipped arenas are {', '.join(ARENA_NAMES)}, "
                "or give a path to a .json file"
            )
        resource = resources.files("sim") / "arenas" / f"{as_text}.json"
        return resource.read_text(encoding="utf-8"), f"arena {as_text!r}"
    path = Path(name_or_path)
    try:
        return path.read_text(encoding="utf-8"), str(path)
    except FileNotFoundError:
        raise ArenaError(f"{path}: arena file not found") from None
    except (OSError, UnicodeDecodeError) as err:
        raise ArenaError(f"{path}: cannot read arena file: {err}") from None


def arena_from_spec(spec: ArenaSpec, source: str = "arena") -> Arena:
    """Check an arena's geometry and build it.

    Raises:
        ArenaError: the outer wall is open or self-intersecting, an obstacle leaves the arena or
            crosses itself, a start pose is outside the arena, inside an obstacle or closer than
            a body radius to a wall, or names repeat.
    """
    where = f"{source}"
    outer_pts = np.asarray(spec.outer_wall, dtype=np.float64)
    if not np.array_equal(outer_pts[0], outer_pts[-1]):
        raise ArenaError(
            f"{where}: outer_wall is not closed: it starts at {_shown(outer_pts[0])} "
            f"but ends at {_shown(outer_pts[-1])} (repeat the first point at the end)"
        )
    outer = outer_pts[:-1]
    _check_simple(outer, closed=True, what=f"{where}: outer_wall")
    if abs(_signed_area(outer)) < _EPS:
        raise ArenaError(f"{where}: outer_wall encloses no area")
    xmin, ymin = outer.min(axis=0)
    xmax, ymax = outer.max(axis=0)
    if max(xmax - xmin, ymax - ymin) > MAX_EXTENT_MM:
        raise ArenaError(
            f"{where}: outer_wall spans {xmax - xmin:g} × {ymax - ymin:g} mm, "
            f"more than the {MAX_EXTENT_MM:g} mm an arena may span"
        )
    walls = [_segments(outer, closed=True)]
    solids = []
    names = [o.name for o in spec.obstacles]
    if len(set(names)) != len(names):
        raise ArenaError(f"{where}: obstacle names repeat: {names}")
    outer_segs = walls[0]
    for i, obstacle in enumerate(spec.obstacles):
        label = f"{where}: obstacles[{i}] ({obstacle.name!r})"
        pts = np.asarray(obstacle.points, dtype=np.float64)
        closed = obstacle.shape == "polygon"
        if closed and len(pts) < 3:
            raise ArenaError(f"{label}: a polygon needs at least 3 points")
        if closed and np.array_equal(pts[0], pts[-1]):
            pts = pts[:-1]
        _check_simple(pts, closed=closed, what=label)
        segs = _segments(pts, closed=closed)
        mids = segs.mean(axis=1)
        probe = np.concatenate([pts, mids])
        on_outer = point_segment_distance(probe, outer_segs).min(axis=-1) <= _EPS
        if not np.all(point_in_polygon(probe, outer) | on_outer):
            raise ArenaError(f"{label}: lies (partly) outside the outer wall")
        if _any_proper_crossing(segs, outer_segs):
            raise ArenaError(f"{label}: crosses the outer wall")
        walls.append(segs)
        if closed:
            solids.append(pts)
    all_walls = np.concatenate(walls)

    start_names = tuple(p.name for p in spec.start_poses)
    if len(set(start_names)) != len(start_names):
        raise ArenaError(f"{where}: start pose names repeat: {list(start_names)}")
    poses = np.array(
        [[p.x, p.y, np.deg2rad(p.heading_deg)] for p in spec.start_poses], dtype=np.float64
    )
    for i, (pose, name) in enumerate(zip(poses, start_names, strict=True)):
        label = f"{where}: start_poses[{i}] ({name!r}) at ({pose[0]:g}, {pose[1]:g})"
        if not point_in_polygon(pose[:2], outer):
            raise ArenaError(f"{label} is outside the outer wall")
        for j, solid in enumerate(solids):
            if point_in_polygon(pose[:2], solid):
                raise ArenaError(f"{label} is inside an obstacle (polygon {j})")
        gap = float(point_segment_distance(pose[:2], all_walls).min())
        if gap <= BODY_RADIUS_MM:
            raise ArenaError(
                f"{label} is {gap:.1f} mm from a wall: the robot (radius {BODY_RADIUS_MM} mm) "
                "would overlap it"
            )

    for array in (all_walls, poses, outer, *solids):
        array.flags.writeable = False
    return Arena(
        name=spec.name,
        walls=all_walls,
        start_poses=poses,
        start_names=start_names,
        bounds=(float(xmin), float(ymin), float(xmax), float(ymax)),
        outer=outer,
        solids=tuple(solids),
        description=spec.description,
    )


# --- plane geometry (load time and tests; not the hot loop) ---


def _segments(points: np.ndarray, closed: bool) -> np.ndarray:
    ends = np.roll(points, -1, axis=0) if closed else points[1:]
    starts = points if closed else points[:-1]
    return np.stack([starts, ends], axis=1)


def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _on_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    return bool(
        min(a[0], b[0]) - _EPS <= p[0] <= max(a[0], b[0]) + _EPS
        and min(a[1], b[1]) - _EPS <= p[1] <= max(a[1], b[1]) + _EPS
    )


def segments_touch(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    """Whether closed segments ab and cd share at least one point."""
    d1, d2 = _cross(c, d, a), _cross(c, d, b)
    d3, d4 = _cross(a, b, c), _cross(a, b, d)
    if ((d1 > _EPS and d2 < -_EPS) or (d1 < -_EPS and d2 > _EPS)) and (
        (d3 > _EPS and d4 < -_EPS) or (d3 < -_EPS and d4 > _EPS)
    ):
        return True
    return (
        (abs(d1) <= _EPS and _on_segment(a, c, d))
        or (abs(d2) <= _EPS and _on_segment(b, c, d))
        or (abs(d3) <= _EPS and _on_segment(c, a, b))
        or (abs(d4) <= _EPS and _on_segment(d, a, b))
    )


def _proper_crossing(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> bool:
    d1, d2 = _cross(c, d, a), _cross(c, d, b)
    d3, d4 = _cross(a, b, c), _cross(a, b, d)
    return d1 * d2 < -_EPS and d3 * d4 < -_EPS


def _any_proper_crossing(segs: np.ndarray, others: np.ndarray) -> bool:
    return any(_proper_crossing(s[0], s[1], o[0], o[1]) for s in segs for o in others)


def _shown(point: np.ndarray) -> str:
    """A point as a message shows it: "(400, 0)"."""
    return "(" + ", ".join(f"{float(v):g}" for v in point) + ")"


def _check_simple(points: np.ndarray, closed: bool, what: str) -> None:
    segs = _segments(points, closed)
    lengths = np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1)
    if np.any(lengths <= _EPS):
        k = int(np.argmax(lengths <= _EPS))
        raise ArenaError(
            f"{what}: segment {k} has zero length (repeated point {_shown(segs[k, 0])})"
        )
    n = len(segs)
    for i in range(n):
        for j in range(i + 1, n):
            adjacent = j == i + 1 or (closed and i == 0 and j == n - 1)
            a, b = segs[i]
            c, d = segs[j]
            if adjacent:
                # Neighbours share one end point; they must not fold back over each other.
                shared = b if j == i + 1 else a
                other_i = a if j == i + 1 else b
                other_j = d if j == i + 1 else c
                folds = (
                    abs(_cross(shared, other_i, other_j)) <= _EPS
                    and np.dot(other_i - shared, other_j - shared) > 0
                )
                if folds:
                    raise ArenaError(f"{what} is self-intersecting: segments {i} and {j} overlap")
            elif segments_touch(a, b, c, d):
                raise ArenaError(
                    f"{what} is self-intersecting: segment {i} {_shown(a)}–{_shown(b)} "
                    f"meets segment {j} {_shown(c)}–{_shown(d)}"
                )


def point_in_polygon(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd test: whether points (..., 2) are inside polygon (M, 2)."""
    p = np.asarray(points, dtype=np.float64)
    x, y = p[..., 0, None], p[..., 1, None]
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    straddles = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    hits = straddles & (x < x_cross)
    return np.asarray(np.count_nonzero(hits, axis=-1) % 2 == 1)


def point_segment_distance(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distances (..., K) from points (..., 2) to segments (K, 2, 2)."""
    p = np.asarray(points, dtype=np.float64)[..., None, :]
    a, b = segments[:, 0], segments[:, 1]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.sum(ab * ab, axis=-1), 0.0, 1.0)
    closest = a + t[..., None] * ab
    return np.asarray(np.linalg.norm(p - closest, axis=-1))
