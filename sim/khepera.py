"""Khepera I constants, after Webots' ``Khepera1.proto`` (docs/decisions.md, "The robot").

Units: millimetres, seconds, radians. Body frame: x forward, y left.
"""

import numpy as np

BODY_RADIUS_MM = 28.5
WHEEL_RADIUS_MM = 7.5
AXLE_MM = 52.0

MAX_COMMAND = 10.0
"""Wheel commands are wheel angular speeds in rad/s, clipped to ±MAX_COMMAND."""
N_WHEELS = 2
"""A step's commands are (N, N_WHEELS): (left, right)."""

N_SENSORS = 8
IR_RANGE_MM = 50.0
IR_MAX = 1023.0
"""A reading is IR_MAX · max(0, 1 − d / IR_RANGE_MM), d the ray length to the nearest wall."""

SENSOR_ORIGINS_MM = np.array(
    [
        [12.1, 25.8],
        [21.4, 18.9],
        [27.5, 7.5],
        [27.5, -7.5],
        [21.4, -18.9],
        [12.1, -25.8],
        [-27.0, -9.0],
        [-27.0, 9.0],
    ]
)
"""(8, 2) sensor origins s0..s7 on the body surface, body frame."""
SENSOR_HEADINGS_RAD = np.deg2rad([85.0, 45.0, 0.0, 0.0, -45.0, -85.0, 180.0, 180.0])
"""(8,) sensor ray directions s0..s7, body frame."""

IR_BACKOFF_MM = 4.0
"""Rays are cast from this far behind each sensor's origin (still inside the body), so a wall
that a sensor has been pushed into (penetration during a contact) reads IR_MAX, not 0."""

CONTROL_PERIOD_S = 0.064
LIFE_STEPS = 1000
"""A training life: T = 1000 control periods (thesis Table 2.4); the lab's training default and
the Gymnasium env's episode length."""

MASS = 70.0
"""Body mass (g). The force drive makes the motion independent of it; it only scales forces."""
MOMENT = 0.5 * MASS * BODY_RADIUS_MM**2
"""Moment of inertia of a uniform disc (g·mm²)."""
