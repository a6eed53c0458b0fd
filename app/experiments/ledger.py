"""A committed report as a ledger of finished runs, so an experiment continues on any machine.

Run files stay on the machine that made them; a committed report does not. Beside its
`values.csv`, a report folder written by `gnp-lab experiment report --out DIR` keeps
`ledger.json`: the engine's bits version and, per finished run (arm, seed), the fingerprint of
the config and implementation conditions it ran. An experiment run with that ledger (by default
the repository's `docs/experiments/NAME-SCALE/`) counts those runs as finished and takes their
values from `values.csv`, so an adaptive run on a fresh clone continues from the last committed
look without rerunning any of them. A ledger of other bits or of another config (the spec
changed) is refused in one line: its values would not be this experiment's.

The values a ledger carries are the report's scalars; a ledger run has no curves (its figures'
curves and the summary's curves are NaN for it).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from app.experiments.planning import Task, plan
from app.experiments.results import ExperimentResults
from app.experiments.spec import ExperimentError, ExperimentSpec
from app.experiments.values import read_values_csv
from app.settings.config import ImplementationSettings, RunConfig
from app.settings.layouts import layout_1
from app.settings.user_files import loads_json, read_text

#: The version of the bits a run produces. Bump it with any change that alters a run's values
#: (the engine, the world, the controller, a default); the tests that pin committed values to the
#: digit fail first. A ledger of other bits is refused.
ENGINE_BITS = 1
FILE = "ledger.json"
FORMAT = "gnp-lab experiment ledger"
DOCS = Path(__file__).resolve().parents[2] / "docs" / "experiments"


def _set(model: type[BaseModel], text: str) -> Any:
    """The settings of `text` that differ from their defaults."""
    return json.loads(model.model_validate_json(text).model_dump_json(exclude_defaults=True))


def _config_identity(text: str) -> Any:
    """A run config's settings that differ from their defaults, in layout 1 (the brain's
    sections at the top, app/settings/layouts.py): the identity every ledger was written with."""
    config = RunConfig.model_validate_json(text)
    return layout_1(json.loads(config.model_dump_json(exclude_defaults=True)), config.brain.family)


def fingerprint(task: Task) -> str:
    """A run's identity: its config and its conditions' settings that differ from their
    defaults, hashed. A setting added later at a default that keeps the bits (a new physics, a
    new noise stream) leaves every committed run's identity as it was; a changed default
    changes the bits, and ENGINE_BITS says so."""
    conditions = [(name, _set(ImplementationSettings, text)) for name, text in task.conditions]
    identity: dict[str, Any] = {
        "config": _config_identity(task.config_json),
        "conditions": conditions,
    }
    if task.task_json:  # a task experiment's run: its brain, task and test seeds too
        identity["task"] = task.task_json
    text = json.dumps(identity)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


@dataclass(frozen=True)
class Ledger:
    """The runs a committed report holds: their names and their values."""

    folder: Path
    runs: frozenset[str]  # task names, "BS-seed3"
    values: ExperimentResults  # the report's scalars over its seeds

    def pending(self, tasks: list[Task]) -> list[Task]:
        """The tasks the ledger does not hold."""
        return [t for t in tasks if t.name not in self.runs]

    def fill(self, results: ExperimentResults) -> ExperimentResults:
        """`results` with the ledger's values where a ledger run has no run file's (NaN)."""
        rows = {seed: i for i, seed in enumerate(self.values.seeds)}
        scalars = {k: v.copy() for k, v in results.scalars.items()}
        for (metric, arm, condition), values in scalars.items():
            theirs = self.values.scalars.get((metric, arm, condition))
            if theirs is None:
                continue
            for i, seed in enumerate(results.seeds):
                held = f"{arm}-seed{seed}" in self.runs and seed in rows
                if held and math.isnan(values[i]):
                    values[i] = theirs[rows[seed]]
        return dataclasses.replace(results, scalars=scalars)


def default_folder(spec: ExperimentSpec, scale: str) -> Path | None:
    """This checkout's committed report folder of the experiment, if it has a ledger."""
    folder = DOCS / f"{spec.name}-{scale}"
    return folder if (folder / FILE).is_file() else None


def finished(spec: ExperimentSpec, scale: str, results: ExperimentResults) -> list[Task]:
    """The runs of `results` that finished: trained, and every condition implemented."""
    finished = {arm.name: results.finished(arm.name) for arm in results.arms}
    return [
        task
        for task in plan(spec, scale, "", max(len(results.seeds), 1))
        if task.seed in results.seeds and finished[task.arm][results.seeds.index(task.seed)]
    ]


def write(spec: ExperimentSpec, scale: str, results: ExperimentResults, folder: Path) -> Path:
    """Write `folder/ledger.json` for the runs of `results` that finished."""
    document = {
        "format": FORMAT,
        "experiment": spec.name,
        "scale": scale,
        "engine_bits": ENGINE_BITS,
        "looks": list(results.looks),
        "runs": {t.name: fingerprint(t) for t in finished(spec, scale, results)},
    }
    path = folder / FILE
    path.write_text(json.dumps(document, indent=1) + "\n")
    return path


def load(spec: ExperimentSpec, scale: str, folder: str | Path) -> Ledger:
    """The ledger in `folder`, checked against this experiment and engine.

    Raises:
        ExperimentError: no ledger there, another experiment's, other engine bits, or a run
            whose config is not the one this spec gives it (the spec changed since).
    """
    folder = Path(folder)
    what = f"ledger {folder / FILE}"
    try:
        document: dict[str, Any] = loads_json(
            read_text(folder / FILE, ExperimentError, "ledger"), ExperimentError, what
        )
    except ExperimentError as error:
        raise ExperimentError(f"no readable ledger in {folder}: {error}") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise ExperimentError(f"{folder / FILE} is not a gnp-lab experiment ledger")
    if (document.get("experiment"), document.get("scale")) != (spec.name, scale):
        raise ExperimentError(
            f"{folder / FILE} is the ledger of {document.get('experiment')!r} at "
            f"{document.get('scale')!r}, not of {spec.name!r} at {scale!r}"
        )
    if document.get("engine_bits") != ENGINE_BITS:
        raise ExperimentError(
            f"{folder / FILE} was made by engine bits {document.get('engine_bits')}, this engine "
            f"makes bits {ENGINE_BITS}: its runs are not this engine's; run with --ledger none"
        )
    runs: dict[str, str] = document.get("runs") or {}
    seeds = {int(name.rsplit("-seed", 1)[1]) for name in runs}
    count = max(seeds) - spec.first_seed + 1 if seeds else 1
    ours = {t.name: fingerprint(t) for t in plan(spec, scale, folder, count)}
    for name, print_ in sorted(runs.items()):
        if ours.get(name) != print_:
            raise ExperimentError(
                f"{folder / FILE}: run {name} was made with another config than {spec.name!r} "
                "gives it now (the spec changed since the ledger was committed); run with "
                "--ledger none"
            )
    import tempfile

    from app.experiments import harvest

    with tempfile.TemporaryDirectory(prefix="gnp-lab-empty-") as empty:
        template = harvest.collect(spec, scale, empty, count)
    values = read_values_csv(folder / "values.csv", spec, template)
    return Ledger(folder, frozenset(runs), values)
