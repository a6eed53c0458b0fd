"""Is the GNP engine a bottleneck? World step alone vs world step + engine step, side by side.

    .venv/bin/python bench/engine.py [--robots 300] [--steps 1000] [--method BS] [--repeats 3]

Both loops observe, step the world and compute the reward; the second also runs `gnp.step`
(learning on, ε = α = 0.1) between observing and stepping, and the first replays the commands
the second produced, so the world does exactly the same work in both. Each loop runs
`--repeats` times, alternating, and the best CPU time (process time: the machine may be shared)
of each is kept. Also prints the engine alone per method on random readings.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import gnp
import sim


def world_loop(world: sim.World, commands: np.ndarray) -> float:
    """CPU seconds of observe → world.step → reward, replaying commands (steps, N, 2)."""
    start = time.process_time()
    for step_commands in commands:
        world.observe()
        world.step(step_commands)
        sim.reward_terms(world.sense(), step_commands)["reward"]
    return time.process_time() - start


def full_loop(
    world: sim.World, cfg: gnp.GnpConfig, pop: gnp.Population, state: gnp.EngineState, steps: int
) -> tuple[float, float, np.ndarray]:
    """CPU seconds of observe → gnp.step → world.step → reward, of gnp.step alone, and the
    commands (steps, N, 2) it produced."""
    reward = np.zeros(world.n)
    log = np.zeros((steps, world.n, 2))
    in_engine = 0.0
    start = time.process_time()
    for t in range(steps):
        obs = world.observe()
        t0 = time.process_time()
        commands = gnp.step(cfg, pop, state, obs, reward, 0.1, 0.1)
        in_engine += time.process_time() - t0
        world.step(commands)
        reward = sim.reward_terms(world.sense(), commands)["reward"]
        log[t] = commands
    return time.process_time() - start, in_engine, log


def engine_alone(method: str, n: int, steps: int) -> float:
    """Controller-steps per second of gnp.step on random readings (fuzzy, learning on)."""
    cfg = gnp.GnpConfig(method=method)  # type: ignore[arg-type]
    rng = np.random.default_rng(0)
    pop = gnp.init_population(cfg, n, rng)
    state = gnp.init_state(cfg, n, np.arange(n))
    obs = rng.uniform(0, 1023, size=(steps, n, 8))
    reward = rng.uniform(0, 1, size=(steps, n))
    gnp.step(cfg, pop, state, obs[0], reward[0], 0.1, 0.1)  # compile / load cache
    start = time.process_time()
    for t in range(steps):
        gnp.step(cfg, pop, state, obs[t], reward[t], 0.1, 0.1)
    return n * steps / (time.process_time() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=300)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--method", choices=["RL", "BS", "CS"], default="BS")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    n, steps = args.robots, args.steps

    arena = sim.load_arena("training")
    cfg = gnp.GnpConfig(method=args.method)
    world = sim.World(arena, n=n, seed=0, noise_sigma=50.0)
    pop = gnp.init_population(cfg, n, np.random.default_rng(0))
    full_loop(world, cfg, pop, gnp.init_state(cfg, n, np.arange(n)), 5)  # warm up numba

    world_times, full_times, engine_times = [], [], []
    for _ in range(args.repeats):
        # The same individuals (fresh Q tables), poses and seeds every time: identical lives.
        pop = gnp.init_population(cfg, n, np.random.default_rng(0))
        state = gnp.init_state(cfg, n, np.arange(n))
        world.reset(np.resize(arena.start_poses, (n, 3)), seeds=np.arange(n))
        total, in_engine, commands = full_loop(world, cfg, pop, state, steps)
        full_times.append(total)
        engine_times.append(in_engine)
        world.reset(np.resize(arena.start_poses, (n, 3)), seeds=np.arange(n))
        world_times.append(world_loop(world, commands))
    t_world, t_full, t_engine = min(world_times), min(full_times), min(engine_times)
    rate = n * steps
    print(
        f"{n} robots × {steps} steps, method {args.method}, fuzzy, σ = 50, best CPU time of "
        f"{args.repeats}"
    )
    print(f"  world alone          {rate / t_world:>12,.0f} robot-steps/s  ({t_world:.3f} s)")
    print(f"  world + gnp.step     {rate / t_full:>12,.0f} robot-steps/s  ({t_full:.3f} s)")
    print(f"  gnp.step share       {1e6 * t_engine / steps:>12.1f} µs per step of {n}")
    print(f"  overhead             {100 * (t_full - t_world) / t_world:>12.1f} %  (full − world)")
    print(f"  engine ÷ world       {100 * t_engine / t_world:>12.1f} %  (gnp.step share ÷ world)")
    for method in ("RL", "BS", "CS"):
        rate = engine_alone(method, n, steps)
        print(f"  engine alone {method}     {rate:>12,.0f} controller-steps/s")


if __name__ == "__main__":
    main()
