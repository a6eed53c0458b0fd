"""Implement a trained run with two sensors breaking, and read the result back.

    python examples/implement_with_a_fault.py RUN.h5

The final elite is cloned into 10 start poses × repeats trials in the unseen implementation
arena; sensors 2 and 3 die at step t' and the robot keeps learning online (Sarsa).
"""

import sys
from pathlib import Path

from app.phases.implementation import implement
from app.settings.config import ImplementationSettings
from app.store import RunReader


def main(run: Path) -> None:
    settings = ImplementationSettings(
        steps=300, fault_step=100, repeats=2, broken_sensors=(2, 3), noise_sigma=50
    )
    result = implement(run, settings, name="sensors-2-3-dead", workers=1)
    before = result.reward_per_step[: settings.fault_step].mean()
    print(f"mean reward per step before the fault {before:.6f}")
    print(f"mean reward per step after the fault {result.mean_after_fault:.6f}")
    with RunReader(run) as reader:
        print(f"implementations stored: {', '.join(reader.implementation_names())}")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
