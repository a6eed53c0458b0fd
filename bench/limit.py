"""What caps the loop: each stage's throughput per core, and the loop's ratio to their limit.

    .venv/bin/python bench/limit.py [--preset thesis-ch3] [--noise 50] [--robots 300]
                                    [--steps 500] [--rounds 3]

One life of `--robots` generation-0 controllers of the preset (σ = `--noise`) is recorded in the
training arena; then each stage replays its share of that life alone, on the recorded inputs:
- sensing: the 8 IR rays of every robot at the recorded poses (`sim.ir_readings`), and the
  same with every wall tested for reach (`sim.rays.ir_readings`, the kernel before the cull);
- noise: what the controllers see (`World.observe`: Eq. 2.6 noise and faults) on those readings,
  with the default noise stream (box-muller-v1) and with ziggurat-v1 (`training.noise_stream`);
- physics pymunk: `World.step` through the recorded commands (the same contacts);
- controller: `gnp.step` (Sarsa on) on the recorded observations and rewards;
- reward: Eq. 2.7 (`sim.reward_table`) on the recorded readings and commands;
- loop: the lab's loop itself (`app.loop.rollout.Batch.step`: all of the above, in turn), step by
  step: in a pymunk world the stages one call at a time, in an analytic world ("loop analytic")
  one compiled call a step (`app.loop.fused`, watched as the dashboard and the recorder watch it);
- rollout analytic: `app.loop.rollout.rollout`, as training and implementation run the loop: k steps
  in one compiled call, robots in blocks (`app.loop.fused`); "rollout zig." the same with
  ziggurat-v1 noise (other draws, so another life than the one recorded: the same work per step).
Each repeat of a loop starts from the life's start (world reset, fresh controllers): it lives the
recorded life. A loop's limit is what its stages add up to (1 / Σ 1/rate); loop / limit below 1
is the loop's own overhead, above 1 what fusing the stages saves (one pass over the robots'
data instead of five). Rates are robot-steps per CPU second of this process (best of `--rounds`,
alternating, so a busy machine's drifts hit every stage alike): per-core throughput. Worlds are
built once, outside the timing (300 copies of an arena's walls take pymunk a few tenths of a
second); each timed life starts with a reset (and fresh controllers): a small share of it.

What each stage's arithmetic costs, against what it takes (the figures `--steps 500` prints on a
loaded 2-core VM, ns per robot-step; issue #31, again after issue #48 on 2026-12-06; the compiled
loop's own profile is docs/speed.md):
- sensing ~105 ns (58 after #48): 8 rays against the 1.2 walls of the robot's cell, one `sincos`:
  ~15 ns;
- noise ~185 ns (121): four Box–Muller pairs, 4 × (`log`, `sqrt`, `sincos`) of glibc and 4
  hashes: ~100-150 ns of libm calls that bit-identity fixes (docs/decisions.md); "noise
  ziggurat-v1" ~40 ns (36; 8 hashes, 8 table look-ups), the faster stream a run may declare
  (`training.noise_stream`), not bit-compatible;
- physics analytic ~345 ns (142; 164-172 at f8707a9 on the same machine): the drive's `sincos`
  of the heading (the turn's comes from a table for whole-number commands), then 3 substeps:
  for the two thirds of robot-steps in free flight (no wall within reach of a period's motion)
  integration alone, ~15 ns; for a robot near a wall, contact search and up to 5 solver passes
  each substep, ~270 ns: chipmunk's branchy contact bookkeeping done operation by operation;
- controller ~210 ns (99): 2-4 visits, each an ε-greedy draw or two, a Sarsa update and 2-3
  dependent loads of the next record: ~20 ns of arithmetic, the rest load latency;
- reward ~20 ns (11): 16 comparisons and a `sqrt`: ~5 ns.

Another physics is one more line in STAGES (as "physics analytic" is), and a loop that runs it
one more line in LOOPS.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

import gnp
import sim
from app.brains.gnp_brain import initial_population
from app.brains.gnp_controllers import gnp_batch
from app.brains.gnp_settings import gnp_settings
from app.loop.rollout import Batch, rollout
from app.loop.seeds import life_seeds
from app.settings.arenas import arena_of
from app.settings.config import RunConfig
from app.settings.loading import build_config, load_preset
from sim import rays
from sim.noise import noise_stream_code, observe, robot_keys


@dataclass(frozen=True)
class Life:
    """One recorded life: the inputs each stage replays (arrays (T, N, ...))."""

    config: RunConfig
    arena: sim.Arena
    start: np.ndarray  # (N, 3) start poses
    world_seeds: np.ndarray  # (N,)
    engine_seeds: np.ndarray  # (N,)
    population: gnp.Population  # before the life (Sarsa changes a copy)
    poses: np.ndarray  # (T, N, 3) after each step (unwrapped, as the world holds them)
    readings: np.ndarray  # (T, N, 8) true readings after each step
    observations: np.ndarray  # (T, N, 8) what the controllers saw before each step
    rewards: np.ndarray  # (T, N) the reward fed to the controllers at each step
    commands: np.ndarray  # (T, N, 2)

    @property
    def work(self) -> int:
        """Robot-steps of the life."""
        return int(self.commands.shape[0] * self.commands.shape[1])

    def world(self, **options: Any) -> sim.World:
        """A world at the life's start (same robots, seeds and noise)."""
        world = sim.World(
            self.arena,
            n=len(self.start),
            seed=self.config.seed,
            noise_sigma=self.config.training.noise_sigma,
            **options,
        )
        world.reset(self.start, seeds=self.world_seeds)
        return world

    def batch(self, world: sim.World) -> Batch:
        """The lab's loop in `world` (at the life's start), with fresh copies of the
        controllers."""
        copy = gnp.take(self.population, np.arange(self.population.size))
        return gnp_batch(
            world, gnp_settings(self.config).controller.gnp_config(), copy, self.engine_seeds
        )


def record(config: RunConfig, robots: int, steps: int) -> Life:
    """Live `steps` steps of `robots` generation-0 controllers of `config` and keep the inputs."""
    grown = build_config(config.model_dump(), {"training": {"population": robots}})
    seeds = life_seeds(grown.seed, 0, np.arange(robots), 1, 10)
    arena = arena_of(grown.training.arena)
    population = initial_population(grown)
    life = Life(
        config=grown,
        arena=arena,
        start=arena.start_poses[seeds.starts[:, 0]],
        world_seeds=seeds.world,
        engine_seeds=seeds.engine,
        population=gnp.take(population, np.arange(robots)),
        poses=np.zeros((steps, robots, 3)),
        readings=np.zeros((steps, robots, sim.N_SENSORS)),
        observations=np.zeros((steps, robots, sim.N_SENSORS)),
        rewards=np.zeros((steps, robots)),
        commands=np.zeros((steps, robots, 2)),
    )
    batch = gnp_batch(
        life.world(), gnp_settings(grown).controller.gnp_config(), population, seeds.engine
    )
    eps, alpha = grown.training.epsilon, grown.training.alpha
    for t in range(steps):
        life.rewards[t] = batch.reward
        step = batch.step(eps, alpha)
        life.observations[t] = step.observations
        life.commands[t] = step.commands
        life.readings[t] = step.readings
        life.poses[t] = batch.world._poses  # unwrapped: the bits the world senses from
    return life


Timed = Callable[[], None]


def sensing(life: Life) -> Timed:
    grid = life.arena.wall_grid
    out = np.empty((life.poses.shape[1], sim.N_SENSORS))

    def run() -> None:
        for poses in life.poses:
            sim.ir_readings(poses, grid, out)

    return run


def sensing_every_wall(life: Life) -> Timed:
    """The kernel before the grid cull (its reference): every wall tested for reach."""
    table = life.arena.wall_table
    out = np.empty((life.poses.shape[1], sim.N_SENSORS))

    def run() -> None:
        for poses in life.poses:
            rays.ir_readings(poses, table, out)

    return run


def noise(life: Life, stream: sim.NoiseStream = sim.DEFAULT_NOISE_STREAM) -> Timed:
    world = life.world()
    mode = np.zeros(life.readings.shape[1:], np.int8)
    stuck = np.zeros(life.readings.shape[1:])
    out = np.empty(life.readings.shape[1:])
    keys = robot_keys(life.world_seeds)
    code = noise_stream_code(stream)
    sigma = world.noise_sigma

    def run() -> None:
        for t, readings in enumerate(life.readings):  # World.observe's kernel, as it calls it
            observe(readings, keys, np.uint64(t), sigma, mode, stuck, out, code)

    return run


def physics(life: Life, **options: Any) -> Timed:
    world = life.world(**options)

    def run() -> None:
        world.reset(life.start, seeds=life.world_seeds)  # a world is built once: a big cost
        for commands in life.commands:
            world.step(commands)

    return run


def controller(life: Life) -> Timed:
    cfg = gnp_settings(life.config).controller.gnp_config()
    eps, alpha = life.config.training.epsilon, life.config.training.alpha

    def run() -> None:
        population = gnp.take(life.population, np.arange(life.population.size))
        state = gnp.init_state(cfg, population.size, life.engine_seeds)
        for seen, reward in zip(life.observations, life.rewards, strict=True):
            gnp.step(cfg, population, state, seen, reward, eps, alpha, True)

    return run


def reward(life: Life) -> Timed:
    out = np.empty((life.commands.shape[1], len(sim.TERM_NAMES)))

    def run() -> None:
        for readings, commands in zip(life.readings, life.commands, strict=True):
            sim.reward_table(readings, commands, out)

    return run


def loop(life: Life, **options: Any) -> Timed:
    """`Batch.step`, step by step: the loop as the dashboard and the recorder run it."""
    eps, alpha = life.config.training.epsilon, life.config.training.alpha
    world = life.world(**options)

    def run() -> None:
        world.reset(life.start, seeds=life.world_seeds)
        batch = life.batch(world)  # fresh controllers: each repeat lives the recorded life
        for _ in range(len(life.commands)):
            batch.step(eps, alpha)

    return run


def rollout_life(life: Life, **options: Any) -> Timed:
    """`app.loop.rollout.rollout`: the loop as training and implementation run it (compiled, for
    GNP controllers in an analytic world: `app.loop.fused`)."""
    eps, alpha = life.config.training.epsilon, life.config.training.alpha
    world = life.world(**options)

    def run() -> None:
        world.reset(life.start, seeds=life.world_seeds)
        rollout(life.batch(world), len(life.commands), eps, alpha)

    return run


STAGES: dict[str, Callable[[Life], Timed]] = {
    "sensing": sensing,
    "sensing, every wall": sensing_every_wall,
    "noise": noise,
    "physics pymunk": physics,
    "physics analytic": lambda life: physics(life, physics="analytic"),
    "controller": controller,
    "reward": reward,
    "loop": loop,
    "loop analytic": lambda life: loop(life, physics="analytic"),
    "rollout analytic": lambda life: rollout_life(life, physics="analytic"),
    "noise ziggurat-v1": lambda life: noise(life, "ziggurat-v1"),
    "rollout zig. analytic": lambda life: rollout_life(
        life, physics="analytic", noise_stream="ziggurat-v1"
    ),
}
"""Each stage's timed replay, built from the recorded life (one line adds a stage)."""
LOOPS = {
    "loop": ("sensing", "noise", "physics pymunk", "controller", "reward"),
    "loop analytic": ("sensing", "noise", "physics analytic", "controller", "reward"),
    "rollout analytic": ("sensing", "noise", "physics analytic", "controller", "reward"),
    "rollout zig. analytic": (
        "sensing",
        "noise ziggurat-v1",
        "physics analytic",
        "controller",
        "reward",
    ),
}
"""Each loop and the stages it runs in turn: their limit is what the loop could reach per core."""


def cpu_seconds(run: Timed) -> float:
    began = time.process_time()
    run()
    return time.process_time() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--preset", default="thesis-ch3")
    parser.add_argument("--noise", type=float, default=50.0)
    parser.add_argument("--robots", type=int, default=300)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    config = build_config(
        load_preset(args.preset).model_dump(), {"training": {"noise_sigma": args.noise}}
    )
    life = record(config, args.robots, args.steps)
    runs = {name: build(life) for name, build in STAGES.items()}
    for run in runs.values():  # numba's kernels loaded, caches filled
        run()
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(args.rounds):
        for name, run in runs.items():
            best[name] = min(best[name], cpu_seconds(run))
    rate = {name: life.work / seconds for name, seconds in best.items()}
    method = gnp_settings(config).controller.method
    print(
        f"{args.preset} ({method}, σ = {args.noise:g}), {args.robots} robots × {args.steps} "
        f"steps; robot-steps per CPU second, best of {args.rounds}"
    )
    print(f"  {'stage':20} {'rate':>12} {'ns/robot-step':>14}")
    for name in runs:
        print(f"  {name:20} {rate[name]:12,.0f} {1e9 / rate[name]:14.0f}")
    for name, stages in LOOPS.items():
        limit = 1.0 / sum(1.0 / rate[stage] for stage in stages)
        print(
            f"  {name}: limit of its stages {limit:,.0f}, {name} / limit {rate[name] / limit:.2f}"
        )


if __name__ == "__main__":
    main()
