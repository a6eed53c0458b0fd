"""Training on Pendulum-v1 through a batch of the lab's compiled twins against Gymnasium's envs:
env-steps per CPU second of whole `train_task` runs (lives, evolution, the run file), GNP-RL and
CMA-ES, both paths in one process, alternating within each round (the order flips every round),
and the two runs' per-generation fitness checked equal.

    .venv/bin/python bench/batch_twin.py [--population 100] [--generations 10] [--rounds 2]

The Gymnasium path is `app.tasks.dynamics.FAST_TASKS` emptied (`SyncVectorEnv` of
`gymnasium.make("Pendulum-v1")`); the twin path is the default (`BatchEnv` mode "twin": every
env of the batch stepped in one compiled call, `app.tasks.pendulum`). Seed 7, lives of 200
steps (Pendulum's time limit; it never terminates). Reported: best of `--rounds` per path, in
millions of env-steps per CPU second of this process (the machine is shared), and twin /
Gymnasium (above 1: the twin is cheaper).

Measured 2026-12-06 on the 2-core development machine (load 5-7: experiments and other
sessions running beside it), population 100, 10 generations (200 k env-steps a run), best of 3:
    Pendulum-v1 gnp-rl     Gymnasium 0.097 M/s   twin 1.108 M/s   11.5x
    Pendulum-v1 cmaes      Gymnasium 0.067 M/s   twin 0.553 M/s    8.3x
(best of 2 in another run: 0.100 against 1.154, 11.6x; 0.066 against 0.514, 7.8x). What is
left is the brains' own step from Python each env step (`gnp.step`: a Box action has no fused
path; CMA-ES's controllers through `generic_lives`), and evolution and the run file.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.settings.loading import build_config
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, read_task_run, train_task
from gnp import Schedule

sys.path.insert(0, str(Path(__file__).parent))
from tasks import gymnasium_path  # bench/tasks.py: the compiled twins unregistered while on

TASK = "Pendulum-v1"


def config(family: str, population: int, generations: int) -> TaskRunConfig:
    """The run of `family` ("gnp-rl" or "cmaes") on Pendulum-v1."""
    if family == "gnp-rl":
        return TaskRunConfig(
            seed=7,
            task=TaskSettings(id=TASK),
            brain=GnpSettings(controller=ControllerSettings(method="RL", fuzzy=False)),
            training=TaskTraining(
                population=population,
                generations=generations,
                steps=200,
                epsilon=Schedule.fixed(0.01),
            ),
        )
    sizes = {"population": population, "generations": generations, "steps": 200}
    run = build_config({"seed": 7, "brain": {"family": family}, "training": sizes})
    return TaskRunConfig.from_run_config(run, TaskSettings(id=TASK))


def run(cfg: TaskRunConfig, folder: Path, name: str) -> tuple[float, np.ndarray]:
    """(env-steps per CPU second, per-generation fitness) of one training run."""
    began = time.process_time()
    done = read_task_run(train_task(cfg, folder / f"{name}.h5"))
    seconds = time.process_time() - began
    assert done.env_steps is not None, "a new run file counts its env steps"
    return float(done.env_steps.sum()) / seconds, done.fitness


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--population", type=int, default=100)
    parser.add_argument("--generations", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    print(f"{TASK}: population {args.population}, {args.generations} generations, "
          f"best of {args.rounds}, env-steps per CPU second")  # fmt: skip
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        for family in ("gnp-rl", "cmaes"):
            for gym_path in (True, False):  # compile numba's kernels outside the clock
                with gymnasium_path(gym_path):
                    run(config(family, 4, 1), folder, f"warm-{family}-{gym_path}")
            best = {True: 0.0, False: 0.0}
            fitness: dict[bool, np.ndarray] = {}
            for r in range(args.rounds):
                for gym_path in (r % 2 == 0, r % 2 == 1):
                    cfg = config(family, args.population, args.generations)
                    with gymnasium_path(gym_path):
                        rate, fitness[gym_path] = run(cfg, folder, f"{family}-{r}-{gym_path}")
                    best[gym_path] = max(best[gym_path], rate)
            if not np.array_equal(fitness[True], fitness[False]):
                raise SystemExit(f"{family}: the twin's run differs from Gymnasium's")
            print(
                f"{TASK} {family:10} Gymnasium {best[True] / 1e6:.3f} M/s   "
                f"twin {best[False] / 1e6:.3f} M/s   {best[False] / best[True]:.1f}x   "
                "(same fitness)"
            )


if __name__ == "__main__":
    main()
