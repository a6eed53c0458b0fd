"""Sensor ray geometry for drawing (the hot loop casts rays in ``sim.kernels``)."""

import numpy as np

from sim.khepera import SENSOR_HEADINGS_RAD, SENSOR_ORIGINS_MM


def sensor_rays(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sensor ray origins and unit directions in the arena frame.

    Args:
        poses: (N, 3) x mm, y mm, heading rad.

    Returns:
        origins (N, 8, 2) mm and directions (N, 8, 2); a ray's reach is ``sim.IR_RANGE_MM``.
    """
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    c = np.cos(poses[:, 2])[:, None]
    s = np.sin(poses[:, 2])[:, None]
    ox, oy = SENSOR_ORIGINS_MM[:, 0], SENSOR_ORIGINS_MM[:, 1]
    origins = np.stack([poses[:, 0:1] + c * ox - s * oy, poses[:, 1:2] + s * ox + c * oy], axis=-1)
    angles = poses[:, 2:3] + SENSOR_HEADINGS_RAD
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    return origins, directions
