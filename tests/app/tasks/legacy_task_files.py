"""Task run files of the old format ("gnp-lab-task-run"), as the lab's `TaskRunWriter` wrote
them before task runs shared the run format (`app.store.legacy` reads them): written here with
raw h5py from a task run of the run format, for tests of what still reads them."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pydantic_core

from app.store import TASK, RunReader
from app.store.files import LIBVER
from app.tasks.config import task_layout_1
from app.tasks.store import read_task_run


def write_old_task_run(
    source: Path,
    out: Path,
    *,
    env_steps: bool = True,
    layout_1: bool = False,
) -> Path:
    """An old-format copy of the task run `source`: its completed generations and checkpoint;
    without `history/env_steps` (a file before #45) unless `env_steps`; its config in layout 1
    (a GNP file before #46) if `layout_1`; a task experiment's `test` group and `peer`
    attribute copied if `source` has them."""
    run = read_task_run(source)
    done = run.generation_done
    with RunReader(source, TASK) as reader:
        point = reader.checkpoint()
        assert point is not None
        best = {
            name: np.asarray(reader.file[f"genomes/best/{name}"][:done])
            for name in reader.file["genomes/best"]
        }
        package_version, seed = reader.package_version, reader.config.seed
    generation, population = point
    n = run.config.training.population
    with h5py.File(out, "w-", libver=LIBVER, locking=False) as handle:
        handle.attrs["format"] = "gnp-lab-task-run"
        handle.attrs["schema_version"] = 1
        handle.attrs["package_version"] = package_version
        handle.attrs["seed"] = seed
        handle.attrs["task"] = run.config.task.id
        data = run.config.model_dump(mode="json")
        text = run.config.model_dump_json()
        handle.attrs["config"] = (
            pydantic_core.to_json(task_layout_1(data)).decode() if layout_1 else text
        )
        handle.attrs["generations_done"] = done
        history = handle.create_group("history")
        fitness = history.create_dataset("fitness", data=run.fitness[:done], maxshape=(None, n))
        fitness.attrs["unit"] = "episode return"
        history.create_dataset("epsilon", data=run.epsilon[:done], maxshape=(None,))
        history.create_dataset("alpha", data=run.alpha[:done], maxshape=(None,))
        if env_steps:
            assert run.env_steps is not None
            steps = np.asarray(run.env_steps[:done], np.int64)
            history.create_dataset("env_steps", data=steps, maxshape=(None,))
            history["env_steps"].attrs["unit"] = "env steps"
        group = history.create_group("best")
        for name, rows in best.items():
            group.create_dataset(name, data=rows, maxshape=(None, *rows.shape[1:]))
        checkpoint = handle.create_group("checkpoint")
        checkpoint.attrs["generation"] = generation
        for name, values in population.items():
            checkpoint.create_dataset(name, data=values)
        with h5py.File(source, "r", locking=False) as new:
            if "test" in new:
                new.copy(new["test"], handle, name="test")
            if "peer" in new.attrs:
                handle.attrs["peer"] = new.attrs["peer"]
    return out
