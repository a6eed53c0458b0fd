"""GNP-RL balances a pole: a GNP population trained on Gymnasium's CartPole-v1.

    python examples/gnp_cartpole.py [--generations 10] [--population 100] [--seed 1] [--out F]

Judgment nodes judge the cart's 4 observation features (scaled to 0..1023 by their bounds),
processing nodes set one output whose sign pushes the cart left or right; each individual lives
one episode per generation, learning by Sarsa, and its return is its fitness. The population
steps together through CartPole's own vector env. Prints the best and mean return of every
generation (500 is the most an episode gives), then replays the final best greedily.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from app.brains.gnp_settings import ControllerSettings, GnpSettings
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, replay_task, train_task
from app.tasks.training import GenerationSummary
from gnp import Schedule


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generations", type=int, default=10)
    parser.add_argument("--population", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, help="run file (default: a temporary one)")
    args = parser.parse_args()
    config = TaskRunConfig(
        seed=args.seed,
        task=TaskSettings(id="CartPole-v1"),
        brain=GnpSettings(controller=ControllerSettings(method="RL", fuzzy=False)),
        training=TaskTraining(
            population=args.population,
            generations=args.generations,
            epsilon=Schedule.fixed(0.01),
            alpha=Schedule.fixed(0.1),
        ),
    )

    def progress(g: GenerationSummary) -> None:
        print(
            f"generation {g.generation}: best return {g.best_fitness:.1f}, "
            f"mean return {g.mean_fitness:.1f} ({g.steps / g.seconds:,.0f} env-steps/s)"
        )

    with tempfile.TemporaryDirectory() as folder:
        out = args.out or Path(folder) / "cartpole.h5"
        train_task(config, out, progress)
        replay = replay_task(out, seed=12345, epsilon=0.0)
        print(f"greedy replay of the final best: return {replay.episode_return:.1f}")


if __name__ == "__main__":
    main()
