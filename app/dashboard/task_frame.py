"""A task's picture: its own `render_mode="rgb_array"` frame, or, for CartPole when Gymnasium's
renderer cannot run (pygame, from `gymnasium[classic-control]`, is not installed), the same
picture drawn here with numpy from the environment's state (no viser, no pygame).

Gymnasium's CartPole frame is 600 x 400: the track at 100 px from the bottom, the cart 50 x 30
px, the pole 10 px wide and 2 x `length` world units long, 600 / 4.8 px per metre; the sketch
keeps that geometry and those colours.
"""

from __future__ import annotations

from typing import Any

import numpy as np

WIDTH, HEIGHT = 600, 400
CART = (0, 0, 0)
POLE = (202, 152, 101)
AXLE = (129, 132, 203)


class FrameError(RuntimeError):
    """No frame for this task: the renderer cannot run and the lab has no sketch of it."""


def _polygon_mask(corners: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Pixels inside a convex polygon (corners counter-clockwise, pixel coordinates)."""
    inside = np.ones(xs.shape, bool)
    for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
        inside &= (b[0] - a[0]) * (ys - a[1]) - (b[1] - a[1]) * (xs - a[0]) >= 0
    return inside


def cartpole_sketch(state: np.ndarray, x_threshold: float = 2.4, length: float = 0.5) -> np.ndarray:
    """(400, 600, 3) uint8 picture of CartPole in `state` (x, ẋ, θ, θ̇), as Gymnasium draws it."""
    x, _, theta, _ = (float(v) for v in state)
    frame = np.full((HEIGHT, WIDTH, 3), 255, np.uint8)
    scale = WIDTH / (2 * x_threshold)
    pole_w, pole_len, cart_w, cart_h, cart_y = 10.0, scale * 2 * length, 50.0, 30.0, 100.0
    # Pixel centres in a frame whose y grows upwards (the picture is flipped at the end).
    ys, xs = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64) + 0.5
    cart_x = x * scale + WIDTH / 2.0
    frame[np.abs(ys - cart_y) < 0.5] = 0  # the track
    cart = (np.abs(xs - cart_x) <= cart_w / 2) & (ys >= cart_y) & (ys <= cart_y + cart_h)
    frame[cart] = CART
    axle_y = cart_y + cart_h * 3 / 4
    corners = np.array(
        [[-pole_w / 2, -pole_w / 2], [pole_w / 2, -pole_w / 2],
         [pole_w / 2, pole_len - pole_w / 2], [-pole_w / 2, pole_len - pole_w / 2]]
    )  # fmt: skip
    c, s = np.cos(-theta), np.sin(-theta)
    rotated = corners @ np.array([[c, s], [-s, c]]) + [cart_x, axle_y]
    frame[_polygon_mask(rotated, xs, ys)] = POLE
    frame[(xs - cart_x) ** 2 + (ys - axle_y) ** 2 <= (pole_w / 2) ** 2] = AXLE
    return np.ascontiguousarray(frame[::-1])


def task_frame(env: Any) -> np.ndarray:
    """The env's current frame: its own renderer's, else the lab's sketch of a known task.

    Raises:
        FrameError: one line: why there is no frame (a missing extra, say).
    """
    try:
        frame = env.render()
    except Exception as error:  # a renderer's missing extra (DependencyNotInstalled), any failure
        unwrapped = env.unwrapped
        if (
            type(unwrapped).__name__ == "CartPoleEnv"
            and getattr(unwrapped, "state", None) is not None
        ):
            return cartpole_sketch(
                np.asarray(unwrapped.state), unwrapped.x_threshold, unwrapped.length
            )
        raise FrameError(f"no frame: {str(error).splitlines()[0]}") from None
    if frame is None:
        raise FrameError("no frame: the task renders nothing in rgb_array mode")
    image = np.asarray(frame)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise FrameError(f"no frame: the task's frame has shape {image.shape}")
    return image.astype(np.uint8, copy=False)
