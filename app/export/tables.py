"""CSV tables of a run (stdlib csv, one header row): the fitness per generation and the reward
per step of each stored implementation phase.

Floats are written with Python's shortest round-trip repr, so reading a value back gives the
run file's float64 exactly.
"""

from __future__ import annotations

import csv
from pathlib import Path

from app.store import RunReader

FITNESS_COLUMNS = ("generation", "best_fitness", "mean_fitness", "std_fitness", "epsilon", "alpha")
IMPLEMENTATION_COLUMNS = ("step", "reward_per_step")


def write_fitness(reader: RunReader, path: Path) -> Path:
    """`fitness.csv`: one row per completed generation."""
    history = reader.history()
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(FITNESS_COLUMNS)
        for g in range(len(history.best_fitness)):
            writer.writerow(
                [
                    g,
                    float(history.best_fitness[g]),
                    float(history.mean_fitness[g]),
                    float(history.std_fitness[g]),
                    float(history.epsilon[g]),
                    float(history.alpha[g]),
                ]
            )
    return path


def implementation_file_name(name: str) -> str:
    """The table of an implementation phase (its names are already file-safe)."""
    return f"implementation-{name}.csv"


def write_implementations(reader: RunReader, folder: Path) -> list[Path]:
    """`implementation-<name>.csv` per stored implementation phase: reward per step, mean over
    its trials."""
    paths = []
    for name in reader.implementation_names():
        result = reader.implementation(name)
        path = folder / implementation_file_name(name)
        with path.open("w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(IMPLEMENTATION_COLUMNS)
            for t, reward in enumerate(result.reward_per_step):
                writer.writerow([t, float(reward)])
        paths.append(path)
    return paths
