"""How fast is the world? The batched World against a naive one-space-per-robot reference.

    .venv/bin/python bench/world.py [--robots 300] [--steps 1000] [--naive-robots 30]
                                    [--naive-steps 300] [--repeats 3]

Both sides do the same work per robot-step: cast the 8 IR rays, add Eq. 2.6 noise (σ = 50),
and advance the physics one 64 ms control period (force drive, 3 substeps) under random wheel
commands. The batched World uses one pymunk space, `pymunk.batch` and numba kernels; the naive
reference gives each robot its own pymunk space, drives it through Python attributes and casts
rays with pymunk's `segment_query_first`. Two command patterns: `iid` draws fresh commands every
step (robots jitter, rarely touch walls), `held` holds mostly-forward commands for 8 steps
(a third of the robots press on walls at any time; contacts are what pymunk spends time on).
Times are CPU seconds of this process (the machine may be shared), best of `--repeats`
alternating runs.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pymunk

import sim
from sim.khepera import (
    AXLE_MM,
    BODY_RADIUS_MM,
    IR_BACKOFF_MM,
    IR_MAX,
    IR_RANGE_MM,
    MASS,
    MOMENT,
    SENSOR_HEADINGS_RAD,
    SENSOR_ORIGINS_MM,
    WHEEL_RADIUS_MM,
)
from sim.spaces import RAY_FILTER, ROBOT_FILTER, SOLVER_ITERATIONS, WALL_FILTER
from sim.world import DEFAULT_SUBSTEPS

SIGMA = 50.0


def commands_for(pattern: str, rng: np.random.Generator, steps: int, n: int) -> np.ndarray:
    """(steps, n, 2) random wheel commands."""
    if pattern == "iid":
        return rng.uniform(-10, 10, (steps, n, 2))
    blocks = rng.uniform(-10, 10, (steps // 8 + 1, n, 2))
    blocks = np.where(rng.random((steps // 8 + 1, n, 1)) < 0.6, np.abs(blocks), blocks)
    return np.repeat(blocks, 8, axis=0)[:steps]


def batched(arena: sim.Arena, poses: np.ndarray, commands: np.ndarray) -> float:
    """CPU seconds for the batched World to observe and step through commands."""
    world = sim.World(arena, n=len(poses), seed=0, noise_sigma=SIGMA)
    world.reset(poses)
    world.observe()
    start = time.process_time()
    for command in commands:
        world.observe()
        world.step(command)
    return time.process_time() - start


class NaiveRobot:
    """One robot in its own pymunk space, driven and sensed one Python call at a time."""

    def __init__(self, arena: sim.Arena, pose: np.ndarray, seed: int) -> None:
        self.space = pymunk.Space()
        self.space.damping = 0.0
        self.space.iterations = SOLVER_ITERATIONS
        for a, b in arena.walls:
            wall = pymunk.Segment(self.space.static_body, tuple(a), tuple(b), 0.0)
            wall.filter = WALL_FILTER
            self.space.add(wall)
        self.body = pymunk.Body(MASS, MOMENT)
        self.body.position = (float(pose[0]), float(pose[1]))
        self.body.angle = float(pose[2])
        shape = pymunk.Circle(self.body, BODY_RADIUS_MM)
        shape.filter = ROBOT_FILTER
        self.space.add(self.body, shape)
        self.rng = np.random.default_rng(seed)

    def observe(self) -> list[float]:
        x, y = self.body.position
        a = self.body.angle
        c, s = np.cos(a), np.sin(a)
        readings = []
        for (ox, oy), h in zip(SENSOR_ORIGINS_MM, SENSOR_HEADINGS_RAD, strict=True):
            dx, dy = np.cos(a + h), np.sin(a + h)
            sx, sy = x + c * ox - s * oy, y + s * ox + c * oy
            start = (sx - IR_BACKOFF_MM * dx, sy - IR_BACKOFF_MM * dy)
            end = (sx + IR_RANGE_MM * dx, sy + IR_RANGE_MM * dy)
            hit = self.space.segment_query_first(start, end, 0.0, RAY_FILTER)
            value = 0.0
            if hit is not None:
                d = max(0.0, hit.alpha * (IR_RANGE_MM + IR_BACKOFF_MM) - IR_BACKOFF_MM)
                value = IR_MAX * max(0.0, 1.0 - d / IR_RANGE_MM)
            readings.append(min(IR_MAX, max(0.0, value + self.rng.normal(0.0, SIGMA))))
        return readings

    def step(self, left: float, right: float, dt: float) -> None:
        speed = WHEEL_RADIUS_MM * (left + right) / 2
        spin = WHEEL_RADIUS_MM * (right - left) / AXLE_MM
        for _ in range(DEFAULT_SUBSTEPS):
            a = self.body.angle
            self.body.force = (MASS * speed * np.cos(a) / dt, MASS * speed * np.sin(a) / dt)
            self.body.torque = MOMENT * spin / dt
            self.space.step(dt)


def naive(arena: sim.Arena, poses: np.ndarray, commands: np.ndarray) -> float:
    """CPU seconds for the naive reference to observe and step through commands."""
    robots = [NaiveRobot(arena, pose, i) for i, pose in enumerate(poses)]
    dt = 0.064 / DEFAULT_SUBSTEPS
    start = time.process_time()
    for command in commands:
        for robot, (left, right) in zip(robots, command, strict=True):
            robot.observe()
            robot.step(float(left), float(right), dt)
    return time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=300)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--naive-robots", type=int, default=30)
    parser.add_argument("--naive-steps", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    arena = sim.load_arena("training")
    rng = np.random.default_rng(0)
    poses = arena.start_poses[rng.integers(0, 10, args.robots)]
    batched(arena, poses[:2], commands_for("iid", rng, 2, 2))  # compile / load numba caches
    print(f"{args.robots} robots × {args.steps} steps (batched) vs "
          f"{args.naive_robots} robots × {args.naive_steps} steps (naive), CPU time, "
          f"best of {args.repeats}")  # fmt: skip
    for pattern in ("iid", "held"):
        commands = commands_for(pattern, rng, args.steps, args.robots)
        slow_commands = commands[: args.naive_steps, : args.naive_robots]
        fast = slow = np.inf
        for _ in range(args.repeats):  # alternate, so both see the same machine load
            fast = min(fast, batched(arena, poses, commands))
            slow = min(slow, naive(arena, poses[: args.naive_robots], slow_commands))
        fast_rate = args.robots * args.steps / fast
        slow_rate = args.naive_robots * args.naive_steps / slow
        print(
            f"{pattern:>5}: batched {fast_rate:>11,.0f} robot-steps/s "
            f"({fast / args.steps * 1e3:.2f} ms per step of {args.robots})   "
            f"naive {slow_rate:>8,.0f} robot-steps/s ({1e6 / slow_rate:.1f} µs per robot-step)   "
            f"ratio {fast_rate / slow_rate:.0f}×"
        )


if __name__ == "__main__":
    main()
