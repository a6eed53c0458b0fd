"""Throughput of the lab's loop against the bare world, side by side in one run.

    .venv/bin/python bench/training.py [--population 300] [--steps 1000] [--generations 3]
                                       [--trials 1000] [--impl-steps 3000] [--rounds 2]

Measures, alternating in rounds so that the machine's drifts hit every figure alike:
- the bare world: `sim` alone, 300 robots, fresh random commands, observe + step, one process;
- the bare world replaying the commands that generation-0 controllers of the same config gave
  in the lab's loop: the same physics (contacts included) without the controllers, the reward
  and the loop, so its ratio to the loop in one process is what the loop adds to the world;
- the full training loop: the thesis-ch3 config (BS, σ = 0, 300 individuals × 1000 steps), one
  generation = evaluate + evolve + write, through `app.phases.training.train` on 1 and 2 workers
  (worker start-up and the first generation excluded);
- the implementation phase: the trained-config individual cloned into `--trials` trials of
  `--impl-steps` steps, on 1 and 2 workers.
Figures are robot-steps per wall-clock second (the workers run in parallel) and each one's
ratio to the bare world. On a machine that other work keeps busy, a second worker finds no idle
core: the last line estimates the implementation's 2-worker ratio on two idle cores from CPU
seconds instead (each process's CPU time, the busiest one's bounding the wall time).
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

import sim
from app.brains.gnp_brain import initial_population
from app.brains.gnp_controllers import gnp_batch
from app.brains.gnp_settings import gnp_settings
from app.brains.registry import family_of
from app.loop.seeds import life_seeds
from app.phases.implementation import run_implementation
from app.phases.training import GenerationSummary, train
from app.settings.loading import build_config, load_preset


def bare_world(robots: int, steps: int) -> float:
    """Seconds for the bare world to observe and step `steps` times under random commands."""
    arena = sim.load_arena("training")
    world = sim.World(arena, n=robots, seed=0)
    world.reset(np.resize(arena.start_poses, (robots, 3)))
    commands = np.random.default_rng(0).uniform(-10, 10, (steps, robots, 2))
    world.observe()
    began = time.perf_counter()
    for command in commands:
        world.observe()
        world.step(command)
    return time.perf_counter() - began


def loop_commands(steps: int) -> tuple[sim.World, np.ndarray, np.ndarray, np.ndarray]:
    """A world as the loop evaluates generation 0 of thesis-ch3 in, its start poses and
    robot seeds, and the (steps, 300, 2) commands the controllers gave there."""
    config = load_preset("thesis-ch3")
    cfg = gnp_settings(config).controller.gnp_config()
    seeds = life_seeds(config.seed, 0, np.arange(300), 1, 10)
    arena = sim.load_arena("training")
    world = sim.World(arena, n=300, seed=config.seed, noise_sigma=config.training.noise_sigma)
    poses = arena.start_poses[seeds.starts[:, 0]]
    world.reset(poses, seeds=seeds.world)
    batch = gnp_batch(world, cfg, initial_population(config), seeds.engine)
    commands = np.array([batch.step(0.1, 0.1).commands for _ in range(steps)])
    return world, poses, seeds.world, commands


def bare_world_replay(
    world: sim.World, poses: np.ndarray, seeds: np.ndarray, commands: np.ndarray
) -> float:
    """Seconds for the bare world to observe and step through the loop's own commands."""
    world.reset(poses, seeds=seeds)
    world.observe()
    began = time.perf_counter()
    for command in commands:
        world.observe()
        world.step(command)
    return time.perf_counter() - began


def training_loop(population: int, steps: int, generations: int, workers: int) -> float:
    """Median seconds per generation of the full training loop, first generation excluded."""
    config = build_config(
        load_preset("thesis-ch3").model_dump(),
        {"training": {"population": population, "steps": steps, "generations": generations}},
    )
    seconds: list[float] = []

    def progress(summary: GenerationSummary) -> None:
        seconds.append(summary.seconds)

    with tempfile.TemporaryDirectory() as folder:
        train(config, Path(folder) / "bench.h5", workers=workers, progress=progress)
    return float(np.median(seconds[1:]))


def implementation(trials: int, steps: int, workers: int) -> float:
    """Seconds for the implementation phase of a generation-0 individual."""
    return implementation_cpu(trials, steps, workers)[0]


def implementation_cpu(trials: int, steps: int, workers: int) -> tuple[float, float, float]:
    """(wall s, CPU s of this process, CPU s of its children) of the implementation phase."""
    config = load_preset("thesis-ch3")
    individual = initial_population(
        build_config(config.model_dump(), {"training": {"population": 2}})
    )
    settings = config.implementation.model_copy(
        update={"repeats": trials // 10, "steps": steps, "recorded_trials": 3}
    )
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = time.process_time()
    began = time.perf_counter()
    run_implementation(
        family_of(config),
        individual,
        settings,
        seed=0,
        control_period=config.training.control_period,
        name="bench",
        generation=0,
        workers=workers,
    )
    wall = time.perf_counter() - began
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    child_cpu = (after.ru_utime + after.ru_stime) - (children.ru_utime + children.ru_stime)
    return wall, time.process_time() - cpu, child_cpu


def idle_estimate(trials: int, steps: int, rounds: int) -> str:
    """2 workers against 1 on two idle cores, from CPU seconds: the busiest process's CPU time
    (this one, or its child) bounds the wall time when each has a core to itself."""
    one = min(sum(implementation_cpu(trials, steps, 1)[1:]) for _ in range(rounds))
    parts = [implementation_cpu(trials, steps, 2) for _ in range(rounds)]
    busiest = min(max(parent, child) for _, parent, child in parts)
    extra = min(parent + child for _, parent, child in parts) - one
    return (
        f"implementation, 2 workers on 2 idle cores (from CPU seconds): "
        f"{one / busiest:.2f} × 1 worker; the second process costs {extra:+.2f} CPU s"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--population", type=int, default=300)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--generations", type=int, default=3)
    parser.add_argument("--trials", type=int, default=1000)
    parser.add_argument("--impl-steps", type=int, default=3000)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    if args.trials < 10:  # the trials are the arena's 10 start poses, `trials // 10` times each
        parser.error(f"--trials must be at least 10 (got {args.trials})")
    life = args.population * args.steps
    trial_steps = (args.trials // 10 * 10) * args.impl_steps
    replay = loop_commands(args.steps)
    cases = {
        "bare world, 1 process": (lambda: bare_world(300, args.steps), 300 * args.steps),
        "bare world, loop's commands": (lambda: bare_world_replay(*replay), 300 * args.steps),
        "training loop, 1 worker": (
            lambda: training_loop(args.population, args.steps, args.generations, 1),
            life,
        ),
        "training loop, 2 workers": (
            lambda: training_loop(args.population, args.steps, args.generations, 2),
            life,
        ),
        "implementation, 1 worker": (
            lambda: implementation(args.trials, args.impl_steps, 1),
            trial_steps,
        ),
        "implementation, 2 workers": (
            lambda: implementation(args.trials, args.impl_steps, 2),
            trial_steps,
        ),
    }
    implementation(20, 50, 1)  # compile numba's kernels before anything is timed
    best = dict.fromkeys(cases, float("inf"))
    for _ in range(args.rounds):
        for name, (measure, _) in cases.items():
            best[name] = min(best[name], measure())
    bare = 300 * args.steps / best["bare world, 1 process"]
    print(
        f"robot-steps per second (best of {args.rounds} rounds); "
        f"training {args.population} × {args.steps} steps, "
        f"implementation {trial_steps // args.impl_steps} trials × {args.impl_steps} steps"
    )
    for name, (_, work) in cases.items():
        rate = work / best[name]
        print(f"  {name:28} {rate:12,.0f}   {rate / bare:5.2f} × bare world")
    one, two = best["implementation, 1 worker"], best["implementation, 2 workers"]
    print(f"  implementation, 2 workers / 1 worker: {one / two:.2f}×")
    print("  " + idle_estimate(args.trials, args.impl_steps, args.rounds))


if __name__ == "__main__":
    main()
