"""An experiment's folder under the runs dir: where its run files, its kept file and its
summaries live.

`RUNS_DIR/experiments/NAME/SCALE/ARM-seedN.h5` are ordinary run files (their names come from
`planning.plan`), `NAME/experiment.toml` the file a `--file` experiment ran from, and
`NAME/summary-SCALE.h5` the summary (`summary.py`).
"""

from __future__ import annotations

from pathlib import Path

from app.experiments.spec import ExperimentError, ExperimentSpec
from app.experiments.spec_loading import load_file
from app.experiments.spec_tables import check_name
from app.store.files import atomic_file


def experiment_dir(runs_dir: str | Path, name: str) -> Path:
    """`RUNS_DIR/experiments/NAME` (the name is checked: no path escapes the runs dir)."""
    try:
        check_name(name)
    except ValueError as error:
        raise ExperimentError(str(error)) from None
    return Path(runs_dir) / "experiments" / name


DEFINITION = "experiment.toml"  # a --file experiment's own file, kept in its folder


def definition_path(runs_dir: str | Path, name: str) -> Path:
    """`RUNS_DIR/experiments/NAME/experiment.toml`: the file a `--file` experiment ran from."""
    return experiment_dir(runs_dir, name) / DEFINITION


def saved_spec(runs_dir: str | Path, name: str) -> ExperimentSpec | None:
    """The experiment a runs dir keeps the file of (None when its folder has none).

    Raises:
        ExperimentError: the kept file is not a valid experiment named `name`.
    """
    path = definition_path(runs_dir, name)
    if not path.is_file():
        return None
    spec = load_file(path)
    if spec.name != name:
        raise ExperimentError(f"{path} defines experiment {spec.name!r}, not {name!r}")
    return spec


def keep_definition(runs_dir: str | Path, name: str, text: str) -> Path:
    """Keep an experiment's file in its folder (replacing an older copy in one step), so that
    `status`, `report` and the dashboard find it by name."""
    path = definition_path(runs_dir, name)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_file(path, overwrite=True) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def summary_path(runs_dir: str | Path, name: str, scale: str) -> Path:
    """`RUNS_DIR/experiments/NAME/summary-SCALE.h5`."""
    return experiment_dir(runs_dir, name) / f"summary-{scale}.h5"
