"""What the Gymnasium vector env costs over the lab's own batched world step, side by side.

    .venv/bin/python bench/gym_env.py [--robots 300] [--steps 1000] [--rounds 3]
                                      [--physics pymunk] [--noise 50]

Both sides step the same robots from the same start poses and noise streams through the same
held, mostly forward commands (a third of the robots on walls at any time):
- the vector env (`sim.gym_vector.WallFollowVectorEnv`, what ``gymnasium.make_vec(
  "GnpLab/WallFollow-v0", num_envs=N)`` gives): ``envs.step(actions)``;
- the lab's step on a bare `sim.World` (`app.loop.rollout.Batch.staged_step` without a
  controller): ``world.observe()``, ``world.step``, ``world.sense()``, ``sim.reward_table``.
Figures are robot-steps per CPU second of this process (the machine may be shared), best of
`--rounds` alternating rounds; issue #34's target is env cost / world cost ≤ 1.25.

Measured 2026-12-04 on the 2-core development machine (load 5.8-6.5: other sessions and a
nice-19 experiment running), 300 robots × 1000 steps, σ = 50, best of 3-5 rounds, four runs:
pymunk: vector env 0.85-1.02 M, lab's world step 0.96-1.09 M robot-steps/s, ratio 1.06-1.13×;
analytic: vector env 2.21-2.22 M, lab's world step 2.35-2.38 M robot-steps/s, ratio 1.06-1.08×.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import sim
from sim.gym_vector import WallFollowVectorEnv


def held_commands(steps: int, n: int, seed: int = 0) -> np.ndarray:
    """(steps, n, 2) commands held for 8 steps, mostly forward."""
    rng = np.random.default_rng(seed)
    blocks = rng.uniform(-10, 10, (steps // 8 + 1, n, 2))
    blocks = np.where(rng.random((steps // 8 + 1, n, 1)) < 0.6, np.abs(blocks), blocks)
    return np.repeat(blocks, 8, axis=0)[:steps]


def vector_env(
    envs: WallFollowVectorEnv, commands: np.ndarray
) -> tuple[float, np.ndarray, np.ndarray]:
    """CPU seconds of the vector env's steps; its start poses and robot seeds."""
    envs.reset(seed=0)
    poses, seeds = envs.world.poses, envs.world.seeds
    began = time.process_time()
    for command in commands:
        envs.step(command)
    return time.process_time() - began, poses, seeds


def lab_step(world: sim.World, poses: np.ndarray, seeds: np.ndarray, commands: np.ndarray) -> float:
    """CPU seconds of the lab's step (observe, step, sense, reward) on a bare world."""
    world.reset(poses, seeds=seeds)
    began = time.process_time()
    for command in commands:
        world.observe()
        world.step(command)
        sim.reward_table(world.sense(), command)
    return time.process_time() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robots", type=int, default=300)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--physics", choices=sim.PHYSICS, default=sim.DEFAULT_PHYSICS)
    parser.add_argument("--noise", type=float, default=50.0)
    args = parser.parse_args()
    commands = held_commands(args.steps, args.robots)
    envs = WallFollowVectorEnv(
        args.robots, noise=args.noise, physics=args.physics, max_episode_steps=args.steps
    )
    world = sim.World(envs.world.arena, n=args.robots, noise_sigma=args.noise, physics=args.physics)
    _, poses, seeds = vector_env(envs, commands[:10])  # compile numba's kernels first
    lab_step(world, poses, seeds, commands[:10])
    best = {"vector env step": np.inf, "lab's world step": np.inf}
    for _ in range(args.rounds):
        seconds, poses, seeds = vector_env(envs, commands)
        best["vector env step"] = min(best["vector env step"], seconds)
        best["lab's world step"] = min(
            best["lab's world step"], lab_step(world, poses, seeds, commands)
        )
    work = args.robots * args.steps
    print(
        f"robot-steps per CPU second (best of {args.rounds} rounds), {args.robots} robots × "
        f"{args.steps} steps, {args.physics}, σ = {args.noise:g}"
    )
    for name, seconds in best.items():
        print(f"  {name:18} {work / seconds:12,.0f}")
    ratio = best["vector env step"] / best["lab's world step"]
    print(f"  vector env cost / lab's world step cost: {ratio:.2f} × (target ≤ 1.25)")


if __name__ == "__main__":
    main()
