"""How well does a run's final elite follow walls? Reward per step and the share of steps with
the wall in range (C = 1 of Eq. 2.7), in the training arena and in the unseen one.

    python examples/wall_following.py RUN.h5 [--steps 3000] [--plot PATHS.png]

The elite lives one trial from each start pose of each arena, with the run's own noise and
online Sarsa at the run's fixed ε/α, and no sensor breaking. Every trial is recorded, so the
reward terms of every step are at hand. This is how the README's demo figures were measured;
--plot draws the trials' paths in both arenas.
"""

import argparse
from pathlib import Path

import numpy as np

import sim
from app.brains.registry import family_of
from app.phases.implementation import run_implementation
from app.settings.config import ImplementationSettings
from app.store import RunReader

NEAR_WALL = "reward/near_wall"  # C: 1 iff a wall is in range and the robot is not touching it


def main(run: Path, steps: int, plot: Path | None) -> None:
    with RunReader(run) as reader:
        config = reader.config
        generation = reader.generations_done - 1
        family = family_of(reader.config)
        elite = family.best(reader, generation)
    print(f"run {run.name}: the best of generation {generation}, {steps} steps per trial")
    paths = {}
    for arena in ("training", "implementation"):
        settings = ImplementationSettings.model_validate(
            config.implementation.model_dump()
            | {
                "arena": arena,
                "steps": steps,
                "repeats": 1,
                "recorded_trials": sim.N_START_POSES,  # every trial: one per start pose
                "broken_sensors": [],
                "break_count": 0,
                "noise_sigma": config.training.noise_sigma,
            }
        )
        result = run_implementation(
            family,
            elite,
            settings,
            seed=config.seed,
            control_period=config.training.control_period,
            name="wall-following",
            generation=generation,
        )
        near_wall = float(np.mean(result.trials.terms[NEAR_WALL]))
        print(
            f"{arena} arena: {len(result.trial_mean_reward)} trials, "
            f"reward per step {result.mean_reward:.4f}, "
            f"steps with the wall in range (C = 1) {near_wall:.4f}"
        )
        paths[arena] = result.trials.poses[..., :2]
    if plot is not None:
        _plot(paths, f"{run.name}, generation {generation}", plot)


def _plot(paths: dict[str, np.ndarray], title: str, out: Path) -> None:
    """Each arena's walls and the robot's path in every trial."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(paths), figsize=(6 * len(paths), 5.5))
    for axis, (arena, xy) in zip(axes, paths.items(), strict=True):
        for wall in sim.load_arena(arena).walls:
            axis.plot(wall[:, 0], wall[:, 1], color="black", lw=2)
        for trial in xy:
            axis.plot(trial[:, 0], trial[:, 1], lw=0.6)
        axis.set(title=f"{arena} arena", aspect="equal", xlabel="x (mm)", ylabel="y (mm)")
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(out, dpi=90)
    print(f"wrote {out}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a run file")
    parser.add_argument("--steps", type=int, default=3000, help="steps per trial")
    parser.add_argument("--plot", type=Path, help="draw the paths into this PNG")
    args = parser.parse_args()
    main(args.run, args.steps, args.plot)
