"""`controller.json`: one generation's best individual as a gnp-lab controller file.

The document is `app.store.controller_file`'s (docs/controller-format.md); its `settings` say what
the lab ran the controller with, so someone can run it in their own code without the run file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from app.brains.registry import family_of
from app.store import RunReader
from app.store.controller_file import save_document


def controller_settings(reader: RunReader, generation: int) -> dict[str, Any]:
    """What the controller ran with in `generation`: run, generation, the family's own
    (GNP's method and judgment; another family's name), seed, control period, ε/α and schedule
    (a family that learns online), fitness, version."""
    training = reader.config.training
    history = reader.history()
    family = family_of(reader.config)
    about: dict[str, Any] = {"run": reader.path.stem, "generation": generation}
    about |= family.export_settings()
    about |= {"seed": reader.seed, "control_period": training.control_period}
    if family.learns_online:
        about |= {
            "epsilon": float(history.epsilon[generation]),
            "alpha": float(history.alpha[generation]),
            "schedule": training.schedule,
        }
    about |= {
        "fitness": float(history.best_fitness[generation]),
        "gnp_lab_version": reader.package_version,
    }
    return about


def write_controller(reader: RunReader, generation: int, path: Path) -> Path:
    """Write the best individual of `generation` (what it learned included) as `path`."""
    family = family_of(reader.config)
    individual = family.best(reader, generation)
    document = family.controller_document(individual, controller_settings(reader, generation))
    return save_document(path, document)
