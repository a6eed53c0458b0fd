"""How well does a run's final elite follow walls? Reward per step and the share of steps with
the wall in range (C = 1 of Eq. 2.7), in the training arena and in the unseen one.

    python examples/wall_following.py RUN.h5 [STEPS]

The elite lives one trial from each start pose of each arena, with the run's own noise and
online Sarsa at the run's fixed ε/α, and no sensor breaking. Every trial is recorded, so the
reward terms of every step are at hand. This is how the README's demo figures were measured.
"""

import sys
from pathlib import Path

import numpy as np

import sim
from app.config import ImplementationSettings
from app.implementation import run_implementation
from app.store import RunReader

NEAR_WALL = "reward/near_wall"  # C: 1 iff a wall is in range and the robot is not touching it


def main(run: Path, steps: int) -> None:
    with RunReader(run) as reader:
        config = reader.config
        generation = reader.generations_done - 1
        cfg, elite = reader.best_genome(generation)
    print(f"run {run.name}: the best of generation {generation}, {steps} steps per trial")
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
            cfg,
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


if __name__ == "__main__":
    main(Path(sys.argv[1]), int(sys.argv[2]) if len(sys.argv) > 2 else 3000)
