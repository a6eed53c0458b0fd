"""How much a smaller working set would buy the compiled loop: the same life, in pieces.

    .venv/bin/python bench/working_set.py [--preset thesis-ch3] [--noise 50] [--robots 320]
                                          [--steps 500] [--rounds 5] [--pieces 64,32,16]

One life of `--robots` generation-0 controllers is recorded (`bench/limit.py`'s `record`), then
lived again by `app.loop.rollout.rollout` (the compiled loop, analytic physics) at once, and as
consecutive rollouts of `piece` robots each: the same robots, seeds and work, so the only
difference is how much of the population's node records (and worlds) one call touches. The
loop already runs robots in blocks of `app.loop.fused.ROBOTS_PER_BLOCK`; a piece of that size
or smaller bounds what a smaller record or a visit-order layout could gain by fitting more of
the walk's records in cache (issue #48). CPU time, best of `--rounds`, alternating.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from limit import Life, cpu_seconds, record, rollout_life

import gnp
from app.loop.fused import ROBOTS_PER_BLOCK
from app.settings.loading import build_config, load_preset


def piece(life: Life, lo: int, hi: int) -> Life:
    """Robots lo..hi−1 of a recorded life, as a life of their own."""
    robots = np.arange(lo, hi)
    return dataclasses.replace(
        life,
        start=life.start[robots],
        world_seeds=life.world_seeds[robots],
        engine_seeds=life.engine_seeds[robots],
        population=gnp.take(life.population, robots),
        poses=life.poses[:, robots],
        readings=life.readings[:, robots],
        observations=life.observations[:, robots],
        rewards=life.rewards[:, robots],
        commands=life.commands[:, robots],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--preset", default="thesis-ch3")
    parser.add_argument("--noise", type=float, default=50.0)
    parser.add_argument("--robots", type=int, default=320)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--pieces", default=f"{ROBOTS_PER_BLOCK},32,16")
    args = parser.parse_args()
    config = build_config(
        load_preset(args.preset).model_dump(), {"training": {"noise_sigma": args.noise}}
    )
    life = record(config, args.robots, args.steps)
    record_bytes = life.population.records.dtype.itemsize
    per_robot = record_bytes * life.population.records.shape[1]
    runs = {"at once": [rollout_life(life, physics="analytic")]}
    for size in (int(s) for s in args.pieces.split(",")):
        parts = range(0, args.robots, size)
        runs[f"pieces of {size}"] = [
            rollout_life(piece(life, lo, min(lo + size, args.robots)), physics="analytic")
            for lo in parts
        ]
    for lives in runs.values():  # kernels loaded, caches filled
        for run in lives:
            run()
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(args.rounds):
        for name, lives in runs.items():
            best[name] = min(best[name], sum(cpu_seconds(run) for run in lives))
    print(
        f"{args.preset}, σ = {args.noise:g}, {args.robots} robots × {args.steps} steps, "
        f"analytic; {per_robot / 1024:.1f} KiB of node records a robot ({record_bytes} B a "
        f"node); the loop's blocks: {ROBOTS_PER_BLOCK} robots; CPU, best of {args.rounds}"
    )
    for name, seconds in best.items():
        ns = seconds / life.work * 1e9
        ratio = best["at once"] / seconds
        print(f"  {name:14} {ns:8.0f} ns/robot-step   at once / this {ratio:.2f}×")


if __name__ == "__main__":
    main()
