"""`controller.json`: one generation's best individual as a gnp-lab controller file.

The document is `app.controller_file`'s (docs/controller-format.md); its `settings` say what
the lab ran the controller with, so someone can run it in their own code without the run file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from app.controller_file import GnpController, NetController, save_controller
from app.store import RunReader


def controller_settings(reader: RunReader, generation: int) -> dict[str, Any]:
    """What the controller ran with in `generation`: control period, ε/α, method, seed, run."""
    training = reader.config.training
    history = reader.history()
    return {
        "run": reader.path.stem,
        "generation": generation,
        "method": reader.config.controller.method,
        "fuzzy": reader.config.controller.fuzzy,
        "seed": reader.seed,
        "control_period": training.control_period,
        "epsilon": float(history.epsilon[generation]),
        "alpha": float(history.alpha[generation]),
        "schedule": training.schedule,
        "fitness": float(history.best_fitness[generation]),
        "gnp_lab_version": reader.package_version,
    }


def write_controller(reader: RunReader, generation: int, path: Path) -> Path:
    """Write the best individual of `generation` (Q tables included) as `path`; a neural run's
    best net."""
    settings = reader.config.neuro
    if settings is not None:
        net = settings.net_config()
        arrays = reader.best_genome_arrays(generation)
        about = controller_settings(reader, generation)
        for gnp_only in ("method", "fuzzy", "epsilon", "alpha", "schedule"):
            del about[gnp_only]  # a net learns nothing online
        about["brain"] = settings.optimiser
        return save_controller(path, NetController(net, arrays, about))
    cfg, individual = reader.best_genome(generation)
    about = controller_settings(reader, generation)
    return save_controller(path, GnpController(cfg, individual, about))
