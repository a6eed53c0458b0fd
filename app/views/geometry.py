"""Pure geometry and colour helpers for the scene: everything here returns numpy arrays of
line segments (S, 2, 3) or colours (S, 2, 3) uint8 ready for viser's `add_line_segments`."""

from __future__ import annotations

import numpy as np

import sim

MM = 1e-3
"""Scene units are metres; the world is in millimetres."""


def circle_segments(centers: np.ndarray, radius: float, n_sides: int = 24) -> np.ndarray:
    """Closed polygons approximating circles.

    Args:
        centers: (R, 2) circle centres.
        radius: circle radius, same units as `centers`.
        n_sides: polygon sides per circle.

    Returns:
        (R * n_sides, 2, 3) segments in the z = 0 plane.
    """
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    angles = np.linspace(0.0, 2.0 * np.pi, n_sides + 1)
    ring = radius * np.stack([np.cos(angles), np.sin(angles)], axis=-1)  # (n_sides + 1, 2)
    points = centers[:, None, :] + ring[None, :, :]
    segments = np.stack([points[:, :-1], points[:, 1:]], axis=2).reshape(-1, 2, 2)
    return flat_to_3d(segments)


def flat_to_3d(segments: np.ndarray, z: float = 0.0) -> np.ndarray:
    """(S, 2, 2) planar segments to (S, 2, 3) at height z."""
    segments = np.asarray(segments, dtype=np.float64)
    out = np.full((*segments.shape[:-1], 3), z)
    out[..., :2] = segments
    return out


def arrow_segments(
    starts: np.ndarray, ends: np.ndarray, head: float, shorten: float = 0.0
) -> np.ndarray:
    """Arrows as line segments: a shaft plus two head strokes at the end.

    Args:
        starts: (S, 2) tails.
        ends: (S, 2) tips.
        head: length of the head strokes.
        shorten: pull both ends in by this much (so arrows stop at a node's rim).

    Returns:
        (3 * S, 2, 3) segments: for arrow i, rows 3i (shaft), 3i + 1 and 3i + 2 (head).
    """
    starts = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
    ends = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
    delta = ends - starts
    length = np.linalg.norm(delta, axis=1, keepdims=True)
    direction = np.divide(delta, length, out=np.zeros_like(delta), where=length > 0)
    pull = np.minimum(shorten, 0.45 * length)
    tail, tip = starts + direction * pull, ends - direction * pull
    cos, sin = np.cos(np.radians(25.0)), np.sin(np.radians(25.0))
    back = -direction
    left = np.stack([back[:, 0] * cos - back[:, 1] * sin, back[:, 0] * sin + back[:, 1] * cos], 1)
    right = np.stack([back[:, 0] * cos + back[:, 1] * sin, -back[:, 0] * sin + back[:, 1] * cos], 1)
    shaft = np.stack([tail, tip], axis=1)
    stroke_left = np.stack([tip, tip + head * left], axis=1)
    stroke_right = np.stack([tip, tip + head * right], axis=1)
    return flat_to_3d(np.stack([shaft, stroke_left, stroke_right], axis=1).reshape(-1, 2, 2))


def cross_segments(centers: np.ndarray, size: float) -> np.ndarray:
    """An X of half-size `size` at each centre: (2 * R, 2, 3)."""
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    d1 = np.array([size, size])
    d2 = np.array([size, -size])
    first = np.stack([centers - d1, centers + d1], axis=1)
    second = np.stack([centers - d2, centers + d2], axis=1)
    return flat_to_3d(np.stack([first, second], axis=1).reshape(-1, 2, 2))


def polyline_segments(points: np.ndarray) -> np.ndarray:
    """Consecutive points (P, 2) joined: (P - 1, 2, 3) segments."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return flat_to_3d(np.stack([points[:-1], points[1:]], axis=1))


_REWARD_STOPS = np.array([[200, 40, 40], [235, 190, 40], [40, 170, 60]], np.float64)


def reward_colors(values: np.ndarray, low: float = 0.0, high: float = 1.0) -> np.ndarray:
    """Red (low) through amber to green (high): (P, 3) uint8, values clipped to [low, high]."""
    t = np.clip((np.asarray(values, np.float64) - low) / (high - low), 0.0, 1.0)
    position = t * (len(_REWARD_STOPS) - 1)
    index = np.minimum(position.astype(np.int64), len(_REWARD_STOPS) - 2)
    frac = (position - index)[..., None]
    rgb = _REWARD_STOPS[index] * (1.0 - frac) + _REWARD_STOPS[index + 1] * frac
    return np.round(rgb).astype(np.uint8)


_READING_LOW = np.array([150, 170, 190], np.float64)
_READING_HIGH = np.array([255, 120, 0], np.float64)


def reading_colors(readings: np.ndarray) -> np.ndarray:
    """Grey-blue for 0 to orange for the sensor's maximum: (..., 3) uint8."""
    t = np.clip(np.asarray(readings, np.float64) / sim.IR_MAX, 0.0, 1.0)[..., None]
    return np.round(_READING_LOW * (1.0 - t) + _READING_HIGH * t).astype(np.uint8)


def segment_colors(point_colors: np.ndarray) -> np.ndarray:
    """Per-point colours (P, 3) to per-vertex colours of the P - 1 joining segments."""
    point_colors = np.asarray(point_colors, np.uint8).reshape(-1, 3)
    return np.stack([point_colors[:-1], point_colors[1:]], axis=1)


def disc_mesh(radius: float, n_sides: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A flat disc in the z = 0 plane: (vertices (n + 1, 3), faces (n, 3))."""
    angles = np.linspace(0.0, 2.0 * np.pi, n_sides, endpoint=False)
    rim = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.zeros(n_sides)], 1)
    vertices = np.concatenate([np.zeros((1, 3)), rim]).astype(np.float32)
    index = np.arange(n_sides)
    faces = np.stack([np.zeros(n_sides, np.int64), 1 + index, 1 + (index + 1) % n_sides], 1)
    return vertices, faces.astype(np.uint32)
