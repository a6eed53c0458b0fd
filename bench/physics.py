"""The analytic physics against pymunk, per core, side by side in one run.

    .venv/bin/python bench/physics.py [--robots 300] [--steps 1000] [--generations 3]
                                      [--rounds 2]

For each physics, alternating in rounds so that the machine's drifts hit both alike:
- the bare world: 300 robots, fresh random commands, observe + step;
- the bare world replaying the commands that generation-0 controllers of thesis-ch3 gave in the
  lab's loop (their contacts), timing `observe` (rays, noise) and `step` (physics) apart;
- the training loop: thesis-ch3 (BS, σ = 50, 300 individuals × 1000 steps) through
  `app.phases.training.train` on 1 worker, in this process; CPU seconds per generation (median,
  the first generation excluded).
Figures are robot-steps per CPU second of this process (the machine may be shared), best of
`--rounds`, and each analytic figure's ratio to the pymunk one.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import sim
from app.brains.gnp_brain import initial_population
from app.brains.gnp_controllers import gnp_batch
from app.brains.gnp_settings import gnp_settings
from app.loop.seeds import life_seeds
from app.phases.training import GenerationSummary, train
from app.settings.loading import build_config, load_preset


def bare_world(physics: sim.Physics, robots: int, steps: int) -> float:
    """CPU seconds for the bare world to observe and step under random commands."""
    arena = sim.load_arena("training")
    world = sim.World(arena, n=robots, seed=0, noise_sigma=50.0, physics=physics)
    world.reset(np.resize(arena.start_poses, (robots, 3)))
    commands = np.random.default_rng(0).uniform(-10, 10, (steps, robots, 2))
    world.observe()
    began = time.process_time()
    for command in commands:
        world.observe()
        world.step(command)
    return time.process_time() - began


def loop_commands(steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The start poses, robot seeds and (steps, 300, 2) commands of thesis-ch3's generation-0
    controllers in the lab's loop."""
    config = load_preset("thesis-ch3")
    seeds = life_seeds(config.seed, 0, np.arange(300), 1, 10)
    arena = sim.load_arena("training")
    world = sim.World(arena, n=300, seed=config.seed, noise_sigma=config.training.noise_sigma)
    poses = arena.start_poses[seeds.starts[:, 0]]
    world.reset(poses, seeds=seeds.world)
    batch = gnp_batch(
        world,
        gnp_settings(config).controller.gnp_config(),
        initial_population(config),
        seeds.engine,
    )
    commands = np.array([batch.step(0.1, 0.1).commands for _ in range(steps)])
    return poses, seeds.world, commands


def replay(
    physics: sim.Physics, poses: np.ndarray, seeds: np.ndarray, commands: np.ndarray
) -> tuple[float, float]:
    """CPU seconds of `observe` and of `step` through the loop's own commands."""
    world = sim.World(sim.load_arena("training"), n=len(poses), noise_sigma=50.0, physics=physics)
    world.reset(poses, seeds=seeds)
    world.observe()
    sensing = physics_time = 0.0
    for command in commands:
        began = time.process_time()
        world.observe()
        middle = time.process_time()
        world.step(command)
        sensing += middle - began
        physics_time += time.process_time() - middle
    return sensing, physics_time


def training_loop(physics: sim.Physics, population: int, steps: int, generations: int) -> float:
    """Median CPU seconds per generation of the training loop on 1 worker, first excluded."""
    config = build_config(
        load_preset("thesis-ch3").model_dump(),
        {
            "training": {
                "population": population,
                "steps": steps,
                "generations": generations,
                "physics": physics,
            }
        },
    )
    marks: list[float] = []

    def progress(_summary: GenerationSummary) -> None:
        marks.append(time.process_time())

    with tempfile.TemporaryDirectory() as folder:
        train(config, Path(folder) / "bench.h5", workers=1, progress=progress)
    return float(np.median(np.diff(marks)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robots", type=int, default=300)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--generations", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    if args.generations < 2:  # a generation is timed from the one before it
        parser.error(f"--generations must be at least 2 (got {args.generations})")
    poses, seeds, commands = loop_commands(args.steps)
    work = args.robots * args.steps
    loop_work = 300 * args.steps
    for physics in sim.PHYSICS:  # compile numba's kernels before anything is timed
        training_loop(physics, 10, 20, 2)
        bare_world(physics, 10, 10)
    best: dict[tuple[str, sim.Physics], float] = {}

    def keep(name: str, physics: sim.Physics, seconds: float) -> None:
        best[name, physics] = min(best.get((name, physics), np.inf), seconds)

    for _ in range(args.rounds):
        for physics in sim.PHYSICS:
            keep(
                "bare world, random commands", physics, bare_world(physics, args.robots, args.steps)
            )
            sensing, stepping = replay(physics, poses, seeds, commands)
            keep("loop's commands: observe + step", physics, sensing + stepping)
            keep("loop's commands: observe only", physics, sensing)
            keep("loop's commands: step only", physics, stepping)
            keep(
                "training loop, 1 worker",
                physics,
                training_loop(physics, 300, args.steps, args.generations),
            )
    print(
        f"robot-steps per CPU second (best of {args.rounds} rounds); bare world {args.robots} "
        f"robots × {args.steps} steps, training thesis-ch3 300 × {args.steps} steps"
    )
    print(f"  {'':34} {'pymunk':>12} {'analytic':>12}  analytic / pymunk")
    names = dict.fromkeys(name for name, _ in best)
    for name in names:
        count = work if name.startswith("bare") else loop_work
        rates = [count / best[name, physics] for physics in sim.PHYSICS]
        print(f"  {name:34} {rates[0]:12,.0f} {rates[1]:12,.0f}  {rates[1] / rates[0]:5.2f} ×")
    loop = {p: best["training loop, 1 worker", p] for p in sim.PHYSICS}
    rest = loop["pymunk"] - best["loop's commands: step only", "pymunk"]
    print(
        f"  the loop without the physics: {loop_work / rest:,.0f} robot-steps/s, so the analytic "
        f"loop can be at most {loop['pymunk'] / rest:.2f} × pymunk's"
    )


if __name__ == "__main__":
    main()
