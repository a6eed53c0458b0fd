"""An executable contract checker for ``sim.World`` (after Gymnasium's env_checker)."""

import numpy as np

from sim.arena import Arena
from sim.khepera import BODY_RADIUS_MM, IR_MAX, MAX_COMMAND
from sim.kinds import DEFAULT_PHYSICS
from sim.world import Physics, World

MAX_PENETRATION_MM = 2.0
"""How far a robot's body may be pushed into a wall during a contact."""


def check_world(
    arena: Arena,
    n: int = 20,
    steps: int = 300,
    seed: int = 0,
    noise_sigma: float = 50.0,
    physics: Physics = DEFAULT_PHYSICS,
) -> None:
    """Assert the world's contract on an arena.

    Two worlds with the same seed, start poses and random commands must give identical poses,
    true readings and observations; readings must stay in 0..1023 and finite; every robot must
    stay inside the outer wall, outside obstacles, and never more than ``MAX_PENETRATION_MM``
    into a wall. ``physics`` names the world's physics.

    Raises:
        AssertionError: naming the step, robot and broken property.
    """
    rng = np.random.default_rng(seed)
    poses = arena.start_poses[rng.integers(0, len(arena.start_poses), n)]
    worlds = [
        World(arena, n=n, seed=seed, noise_sigma=noise_sigma, physics=physics) for _ in range(2)
    ]
    for world in worlds:
        world.reset(poses)
    for t in range(steps):
        true = [w.sense() for w in worlds]
        seen = [w.observe() for w in worlds]
        for name, (a, b) in (("true readings", true), ("observations", seen)):
            assert np.array_equal(a, b), f"step {t}: {name} differ between two same-seed worlds"
            assert np.all(np.isfinite(a)), f"step {t}: {name} contain NaN or infinity"
            assert np.all((a >= 0) & (a <= IR_MAX)), f"step {t}: {name} leave 0..{IR_MAX:g}"
        pose = worlds[0].poses
        assert np.array_equal(pose, worlds[1].poses), f"step {t}: poses differ"
        assert np.all(np.isfinite(pose)), f"step {t}: poses contain NaN or infinity"
        inside = arena.contains(pose[:, :2])
        assert np.all(inside), f"step {t}: robot {int(np.argmin(inside))} left the arena"
        depth = BODY_RADIUS_MM - arena.clearance(pose[:, :2])
        assert np.all(depth <= MAX_PENETRATION_MM), (
            f"step {t}: robot {int(np.argmax(depth))} is {depth.max():.2f} mm into a wall"
        )
        # Hold commands for a few steps so robots reach walls and press on them.
        if t % 8 == 0:
            commands = rng.uniform(-MAX_COMMAND, MAX_COMMAND, (n, 2))
        for w in worlds:
            w.step(commands)
