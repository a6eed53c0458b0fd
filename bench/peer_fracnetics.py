"""Ours against fracnetics on CartPole-v1: episodes and env-steps per second, one run each, the
same population and generations (issue #34 item 3; target: ours at least 5x fracnetics'
env-steps per second).

    .venv/bin/python bench/peer_fracnetics.py [--population 100] [--generations 60] [--seed 1]

Ours: `app.tasks.train_task`, GNP-RL (crisp, epsilon 0.01, alpha 0.1: docs/tasks.md's example),
the whole population's lives batched through CartPole's vector env; numba's kernels are loaded
first by a 1-generation run, not timed. fracnetics: its documented CartPole loop
(`app.tasks.fracnetics_arm.train_fracnetics`, 4.0.0), one `gymnasium.make` env stepped from C++.
Both: one episode per individual per generation, lives capped at 500 steps; the env-steps are
the episodes' lengths (CartPole pays +1 per step, so a fracnetics episode's return is its
length). Reported: wall and CPU seconds of this process, episodes/s and env-steps/s (per CPU
second), and ours over fracnetics'. Training only: neither side's final test episodes count.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


def _ours(population: int, generations: int, seed: int, folder: Path) -> dict[str, float]:
    from app.brains.gnp_settings import ControllerSettings, GnpSettings
    from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, train_task
    from gnp import Schedule

    def config(g: int) -> TaskRunConfig:
        return TaskRunConfig(
            seed=seed,
            task=TaskSettings(id="CartPole-v1"),
            brain=GnpSettings(controller=ControllerSettings(method="RL", fuzzy=False)),
            training=TaskTraining(
                population=population, generations=g, steps=500, epsilon=Schedule.fixed(0.01)
            ),
        )

    train_task(config(1), folder / "warm.h5")  # numba's caches, not timed
    steps = [0]
    best = [0.0]

    def progress(g: object) -> None:
        steps[0] += g.steps  # type: ignore[attr-defined]
        best[0] = g.best_fitness  # type: ignore[attr-defined]

    wall, cpu = time.perf_counter(), time.process_time()
    train_task(config(generations), folder / "ours.h5", progress=progress)
    return _rates(population * generations, steps[0], wall, cpu, best[0])


def _fracnetics(population: int, generations: int, seed: int) -> dict[str, float]:
    from app.tasks.fracnetics_arm import documented, train_fracnetics

    wall, cpu = time.perf_counter(), time.process_time()
    result = train_fracnetics(
        "CartPole-v1",
        documented("CartPole-v1"),
        population,
        generations,
        seed,
        500,
        [0],
        twin=False,  # its own loop on Gymnasium's env, as its notebooks run it
    )
    # the test episode is outside the timing only approximately: one episode of 500 steps at
    # most against population x generations of training (said in the docstring)
    steps = int(result.fitness.sum())  # CartPole: return = episode length
    return _rates(population * generations, steps, wall, cpu, float(result.fitness[-1].max()))


def _rates(episodes: int, steps: int, wall: float, cpu: float, best: float) -> dict[str, float]:
    wall_s, cpu_s = time.perf_counter() - wall, time.process_time() - cpu
    return {
        "episodes": episodes,
        "env_steps": steps,
        "wall_s": wall_s,
        "cpu_s": cpu_s,
        "episodes_per_s": episodes / cpu_s,
        "steps_per_s": steps / cpu_s,
        "best": best,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--population", type=int, default=100)
    parser.add_argument("--generations", type=int, default=60)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="gnp-lab-peer-bench-") as tmp:
        ours = _ours(args.population, args.generations, args.seed, Path(tmp))
    theirs = _fracnetics(args.population, args.generations, args.seed)
    n, g = args.population, args.generations
    print(f"CartPole-v1, population {n}, {g} generations, one run each")
    print(f"{'':12}{'episodes':>10}{'env-steps':>12}{'wall s':>9}{'CPU s':>8}"
          f"{'episodes/s':>12}{'env-steps/s':>13}{'best':>7}")  # fmt: skip
    for name, r in (("ours", ours), ("fracnetics", theirs)):
        print(f"{name:12}{r['episodes']:>10.0f}{r['env_steps']:>12.0f}{r['wall_s']:>9.2f}"
              f"{r['cpu_s']:>8.2f}{r['episodes_per_s']:>12.0f}{r['steps_per_s']:>13.0f}"
              f"{r['best']:>7.0f}")  # fmt: skip
    ratio = ours["steps_per_s"] / theirs["steps_per_s"]
    episodes = ours["episodes_per_s"] / theirs["episodes_per_s"]
    print(f"ours / fracnetics: {ratio:.2f}x env-steps per CPU second (target >= 5x), "
          f"{episodes:.2f}x episodes per CPU second")  # fmt: skip


if __name__ == "__main__":
    main()
