"""Is the GNP engine a bottleneck? World step alone vs world step + engine step, side by side.

    .venv/bin/python bench/engine.py [--robots 300] [--steps 2000] [--block 50]
                                     [--methods RL BS CS] [--rounds 3]

Two identical worlds run in lockstep, block by block: the first runs the lab's loop (observe →
`gnp.step` → world step → reward; learning on, ε = α = 0.1, fuzzy judgment, σ = 50), the
second replays the commands the first produced, so both worlds do exactly the same work. The
blocks alternate every `--block` steps, so the machine's slow drifts hit both loops alike; CPU
time (process time) is summed over blocks after two warm-up blocks.

Printed per method and round: the overhead (full loop − world loop) ÷ world loop, which is what
the engine adds to a world step, cache effects included; the time inside `gnp.step` ÷ world;
and the median and quartiles of the per-block overheads. Also the engine alone per method.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import gnp
import sim


def make_world(arena: sim.Arena, n: int) -> sim.World:
    world = sim.World(arena, n=n, seed=0, noise_sigma=50.0)
    world.reset(np.resize(arena.start_poses, (n, 3)), seeds=np.arange(n))
    return world


def paired_blocks(method: str, n: int, steps: int, block: int) -> tuple[float, float, np.ndarray]:
    """(overhead, engine share, per-block overheads): fractions of the world loop's CPU time."""
    arena = sim.load_arena("training")
    cfg = gnp.GnpConfig(method=method)  # type: ignore[arg-type]
    full, replay = make_world(arena, n), make_world(arena, n)
    pop = gnp.init_population(cfg, n, np.random.default_rng(0))
    state = gnp.init_state(cfg, n, np.arange(n))
    reward = np.zeros(n)
    commands = np.zeros((block, n, 2))
    clock = time.process_time
    t_full = t_world = t_engine = 0.0
    per_block = []
    for b in range(steps // block):
        start, in_engine = clock(), 0.0
        for t in range(block):
            observed = full.observe()
            t0 = clock()
            commands[t], _ = gnp.step(cfg, pop, state, observed, reward, 0.1, 0.1)
            in_engine += clock() - t0
            full.step(commands[t])
            reward = sim.reward_terms(full.sense(), commands[t])["reward"]
        elapsed_full = clock() - start
        start = clock()
        for t in range(block):
            replay.observe()
            replay.step(commands[t])
            sim.reward_terms(replay.sense(), commands[t])["reward"]
        elapsed_world = clock() - start
        if b >= 2:  # warm-up: numba's cache loads, first contacts
            t_full += elapsed_full
            t_world += elapsed_world
            t_engine += in_engine
            per_block.append(elapsed_full / elapsed_world - 1.0)
    if not np.array_equal(full.sense(), replay.sense()):
        raise SystemExit("the replayed world diverged: the comparison would be unfair")
    return t_full / t_world - 1.0, t_engine / t_world, np.array(per_block)


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
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--block", type=int, default=50)
    parser.add_argument("--methods", nargs="+", choices=["RL", "BS", "CS"], default=["BS"])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    n = args.robots
    print(
        f"{n} robots × {args.steps} steps in blocks of {args.block}, fuzzy, σ = 50, "
        f"CPU time; overhead = (world + gnp.step) ÷ world − 1"
    )
    for method in args.methods:
        for _ in range(args.rounds):
            overhead, share, blocks = paired_blocks(method, n, args.steps, args.block)
            q1, median, q3 = 100 * np.percentile(blocks, [25, 50, 75])
            print(
                f"  {method}  overhead {100 * overhead:5.1f} %   in gnp.step {100 * share:5.1f} %"
                f"   per block: median {median:5.1f} %, quartiles {q1:5.1f}..{q3:5.1f} %"
            )
    for method in ("RL", "BS", "CS"):
        rate = engine_alone(method, n, 1000)
        print(f"  engine alone {method}  {rate:>12,.0f} controller-steps/s")


if __name__ == "__main__":
    main()
