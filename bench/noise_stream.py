"""The two noise streams side by side: the noise stage alone and a training generation, CPU time.

    .venv/bin/python bench/noise_stream.py [--population 300] [--steps 1000] [--rounds 3]

- noise stage: `sim.noise.observe` (σ = 50, no fault) on 300 robots' readings for 500 steps,
  in this process, streams alternating, best of `--rounds` × 3; ns per robot-step;
- training generation: `app.phases.training.train` (thesis-ch3, σ = 50, analytic, 1 worker,
  `--population` × `--steps`), the second of three generations (as `bench/versus.py` times it),
  each measurement a fresh process, the streams alternating within each round; best of
  `--rounds`, CPU seconds (the process and its children).
box-muller-v1 is the default (every earlier run's bits); ziggurat-v1 draws other numbers of the
same N(0, σ²) (`training.noise_stream`, docs/decisions.md: A faster noise stream).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from typing import Any

import numpy as np

import sim
from sim import noise

HERE = os.path.dirname(os.path.abspath(__file__))


def noise_stage(rounds: int, robots: int = 300, steps: int = 500) -> dict[str, float]:
    """ns per robot-step of `noise.observe` for each stream."""
    keys = noise.robot_keys(np.arange(robots, dtype=np.uint64))
    readings = np.random.default_rng(0).uniform(0.0, sim.IR_MAX, (steps, robots, sim.N_SENSORS))
    mode = np.zeros((robots, sim.N_SENSORS), np.int8)
    stuck = np.zeros((robots, sim.N_SENSORS))
    out = np.empty((robots, sim.N_SENSORS))

    def run(code: int) -> float:
        began = time.process_time()
        for t in range(steps):
            noise.observe(readings[t], keys, np.uint64(t), 50.0, mode, stuck, out, code)
        return time.process_time() - began

    best = dict.fromkeys(sim.NOISE_STREAMS, float("inf"))
    for stream in sim.NOISE_STREAMS:
        run(noise.noise_stream_code(stream))  # compiled, loaded
    for r in range(3 * rounds):
        order = sim.NOISE_STREAMS if r % 2 == 0 else sim.NOISE_STREAMS[::-1]
        for stream in order:
            best[stream] = min(best[stream], run(noise.noise_stream_code(stream)))
    return {stream: 1e9 * seconds / (robots * steps) for stream, seconds in best.items()}


def generation(population: int, steps: int, stream: str) -> float:
    """CPU seconds of the second of three generations (see bench/versus.py)."""
    sys.path.insert(0, HERE)
    import versus  # bench/versus.py: the same config and timing

    original = versus._config

    def with_stream(population: int, steps: int) -> Any:
        config = original(population, steps)
        training = config.training.model_copy(update={"noise_stream": stream})
        return config.model_copy(update={"training": training})

    versus._config = with_stream
    try:
        return versus.generation(population, steps)[1]
    finally:
        versus._config = original


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--population", type=int, default=300)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        population, steps, stream = args.child
        print(json.dumps(generation(int(population), int(steps), stream)))
        return
    stage = noise_stage(args.rounds)
    best = dict.fromkeys(sim.NOISE_STREAMS, float("inf"))
    for r in range(args.rounds):
        order = sim.NOISE_STREAMS if r % 2 == 0 else sim.NOISE_STREAMS[::-1]
        for stream in order:
            child = [str(args.population), str(args.steps), stream]
            done = subprocess.run(
                [sys.executable, __file__, "--child", *child], check=True, capture_output=True
            )
            cpu = json.loads(done.stdout.decode().strip().splitlines()[-1])
            best[stream] = min(best[stream], cpu)
    old, new = sim.NOISE_STREAMS
    print(f"noise stage (σ = 50, 300 robots × 500 steps), ns/robot-step, best of {3 * args.rounds}")
    for stream in sim.NOISE_STREAMS:
        print(f"  {stream:14} {stage[stream]:7.1f}")
    print(f"  {old} / {new}: {stage[old] / stage[new]:.2f}×")
    print(
        f"training generation (thesis-ch3, σ = 50, analytic, 1 worker, {args.population} × "
        f"{args.steps}), CPU s, best of {args.rounds} alternating rounds"
    )
    for stream in sim.NOISE_STREAMS:
        print(f"  {stream:14} {best[stream]:7.3f}")
    print(f"  {old} / {new}: {best[old] / best[new]:.2f}×")


if __name__ == "__main__":
    main()
