"""GNP on Gymnasium tasks: env-steps per CPU second of a whole GNP-RL generation (lives and
evolution), the Gymnasium path against the lab's compiled path, and fracnetics on CartPole.

    .venv/bin/python bench/tasks.py [--populations 100 300] [--rounds 2] [--seed 1]
                                    [--tasks CartPole-v1 MountainCar-v0 Acrobot-v1]
                                    [--generations 60 10 5] [--no-fracnetics]

For each task and population, both paths train the same run (GNP-RL, crisp, ε = 0.01, lives
capped at the episode's own limit) for the task's generations from the same seed, so they
live the same episodes (tests/app/tasks/test_task_fast.py): the Gymnasium path
(`app.tasks.dynamics.FAST_TASKS` emptied: CartPole's numpy vector env, `SyncVectorEnv` for the
others) and the compiled path (the default). fracnetics (issue #34's peer: GNP in C++ calling
Gymnasium's Python CartPole) runs its documented CartPole loop at population 100 for the same
generations, its env steps counted by a wrapper. Figures are env-steps per CPU second of this
process (the machine is shared), best of `--rounds` alternating rounds.

Measured 2026-12-04 on the 2-core development machine (load 15-20: other sessions' tests and a
nice-19 experiment running), seed 1, best of 2 rounds, env-steps per CPU second (see
docs/decisions.md, "GNP on tasks, compiled"):
    task            N    Gymnasium path   compiled path   compiled / Gymnasium
    CartPole-v1     100      0.61 M           3.83 M          6.3×   (G = 60, 1.60 M steps)
    CartPole-v1     300      0.64 M           2.92 M          4.5×   (G = 60, 3.36 M steps)
    MountainCar-v0  100      0.101 M          2.58 M         25.5×   (G = 10, 0.20 M steps)
    MountainCar-v0  300      0.100 M          2.51 M         25.0×   (G = 10, 0.60 M steps)
    Acrobot-v1      100      0.026 M          1.53 M         59.3×   (G = 5, 0.24 M steps)
    Acrobot-v1      300      0.027 M          1.65 M         60.6×   (G = 5, 0.71 M steps)
    fracnetics, CartPole-v1, N = 100, G = 60: 0.095 M (0.94 M steps in 9.9 CPU s); the
    compiled path is 40× that (20× the 187 k issue #34 measured for fracnetics: 1.75 M steps
    in 9.3 CPU s, a run whose seed is not recorded here).
Again 2026-12-06 (#45's target: the compiled path stays >= 20x fracnetics), seed 1, best of 2
rounds, a quiet machine: CartPole-v1 N = 100, G = 60: Gymnasium path 0.70 M, compiled 4.36 M
(6.2x), fracnetics 0.141 M; compiled / fracnetics 31.0x.
Of the compiled CartPole run at N = 100 (0.41-0.45 CPU s), the compiled lives take 0.15 s (~90 ns an
env step, GNP's walk included), the start states 0.06 s (`np.random.default_rng(s)` per
seed), the rest is the generation's Python: life seeds, `gnp.evolve`, `gnp.take`.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import gymnasium as gym

import gnp
from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.loop.seeds import evolution_rng
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, dynamics
from app.tasks.lives import BatchEnv
from app.tasks.training import first_population, generation_lives
from gnp import Schedule


def config(task: str, population: int, generations: int, seed: int) -> TaskRunConfig:
    return TaskRunConfig(
        seed=seed,
        task=TaskSettings(id=task),
        brain=GnpSettings(controller=ControllerSettings(method="RL", fuzzy=False)),
        training=TaskTraining(
            population=population,
            generations=generations,
            steps=int(gym.spec(task).max_episode_steps or 500),
            epsilon=Schedule.fixed(0.01),
        ),
    )


@contextmanager
def gymnasium_path(on: bool) -> Iterator[None]:
    """The Gymnasium path while on (the lab's compiled tasks unregistered)."""
    kept = dynamics.FAST_TASKS
    if on:
        dynamics.FAST_TASKS = {}
    try:
        yield
    finally:
        dynamics.FAST_TASKS = kept


def gnp_run(cfg: TaskRunConfig) -> tuple[int, float, float]:
    """(env steps, CPU seconds, best return of the last generation) of a training run."""
    gcfg = cfg.gnp_config()
    training = cfg.training
    pop = first_population(cfg)
    env = BatchEnv(cfg.task.id, training.population, cfg.adapter)
    steps = 0
    began = time.process_time()
    try:
        for g in range(training.generations):
            epsilon, alpha = training.epsilon_alpha(g)
            lives = generation_lives(cfg, pop, g, epsilon, alpha, env)
            steps += int(lives.lengths.sum())
            pop = gnp.evolve(
                gcfg, lives.learned, lives.returns, g, training.generations,
                evolution_rng(cfg.seed, g), cfg.gnp_settings().evolution,
            )  # fmt: skip
    finally:
        env.close()
    return steps, time.process_time() - began, float(lives.returns.max())


class StepCount(gym.Wrapper):
    """Counts the env's steps."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.steps = 0

    def step(self, action: Any) -> Any:
        self.steps += 1
        return self.env.step(action)


def fracnetics_run(population: int, generations: int, seed: int) -> tuple[int, float, float]:
    """fracnetics' CartPole loop (its documented settings): (env steps, CPU seconds, best)."""
    import fracnetics as fn

    pop = fn.Population(
        seed=seed, ni=population, jn=1, jnf=4, pn=2, pnf=2, fractalJudgment=False,
        nFeatureValues=[0, 0, 0, 0],
    )  # fmt: skip
    lo, hi = [-4.8, -5, -0.418, -10], [4.8, 5, 0.418, 10]
    pop.setAllNodeBoundaries(lo, hi)
    env = StepCount(gym.make("CartPole-v1"))
    began = time.process_time()
    for g in range(generations):
        pop.gymnasium(env, dMax=10, maxSteps=500, maxConsecutiveP=10, seeds=[seed + g])
        best = float(pop.bestFit)
        pop.tournamentSelection(N=5, E=1)
        pop.callAddDelNodes(lo, hi, 1)
        pop.crossover(probability=0.05, type="uniform")
        pop.callEdgeMutation(probInnerNodes=0.05, probStartNode=0.05)
    return env.steps, time.process_time() - began, best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--tasks", nargs="+", default=["CartPole-v1", "MountainCar-v0", "Acrobot-v1"]
    )
    parser.add_argument("--generations", nargs="+", type=int, default=[60, 10, 5])
    parser.add_argument("--populations", nargs="+", type=int, default=[100, 300])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--no-fracnetics", action="store_true")
    args = parser.parse_args()
    gens = dict(zip(args.tasks, args.generations, strict=True))
    for task in args.tasks:  # compile numba's kernels outside the clock
        gnp_run(config(task, 4, 1, args.seed))
    best: dict[tuple[str, int, str], tuple[float, int, float]] = {}
    for _ in range(args.rounds):
        for task in args.tasks:
            for n in args.populations:
                for path in ("gymnasium", "compiled"):
                    with gymnasium_path(path == "gymnasium"):
                        steps, seconds, top = gnp_run(config(task, n, gens[task], args.seed))
                    key = (task, n, path)
                    if key not in best or seconds < best[key][0]:
                        best[key] = (seconds, steps, top)
        if not args.no_fracnetics and "CartPole-v1" in gens:
            steps, seconds, top = fracnetics_run(100, gens["CartPole-v1"], args.seed)
            key = ("CartPole-v1", 100, "fracnetics")
            if key not in best or seconds < best[key][0]:
                best[key] = (seconds, steps, top)
    print(f"env-steps per CPU second of GNP generations (best of {args.rounds} rounds)")
    rate = {key: steps / seconds for key, (seconds, steps, _) in best.items()}
    for (task, n, path), (seconds, steps, top) in best.items():
        print(
            f"  {task:15} N={n:<4} {path:10} {rate[task, n, path]:12,.0f} steps/s "
            f"({steps:,} steps in {seconds:.2f} CPU s, G={gens[task]}, last best {top:g})"
        )
    for task in args.tasks:
        for n in args.populations:
            ratio = rate[task, n, "compiled"] / rate[task, n, "gymnasium"]
            print(f"  {task} N={n}: compiled / Gymnasium path {ratio:.1f}×")
    peer = ("CartPole-v1", 100, "fracnetics")
    if peer in rate and ("CartPole-v1", 100, "compiled") in rate:
        ratio = rate["CartPole-v1", 100, "compiled"] / rate[peer]
        print(f"  CartPole-v1 N=100: compiled / fracnetics {ratio:.1f}× (issue #45: stays ≥ 20)")


if __name__ == "__main__":
    main()
