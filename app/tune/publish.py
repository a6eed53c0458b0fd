"""A finished study's preset: the best trial's settings, and the record of the study."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.settings.layouts import layout_2
from app.tasks.common import EpisodeProtocol
from app.tune.preset import TuningRecord, now, write_preset
from app.tune.space import FIRST_VALIDATION_SEED, TuneError, nested, run_seeds
from app.tune.study import (
    PRUNE_STARTUP_TRIALS,
    STARTUP_TRIALS,
    Declared,
    finished,
    fracnetics_settings,
    gnp_config,
)

if TYPE_CHECKING:
    import optuna

    from app.tasks.config import TaskSettings

OBJECTIVE = {
    "gnp": "mean return of each run's final elite (the task run's: the last generation's "
    "best, or the one chosen on its own validation episodes) over the validation episodes, "
    "under the test protocol of [task] (greedy: epsilon = 0, learning off), averaged over "
    "the run seeds",
    "fracnetics": "mean return of fracnetics' final elite over the validation episodes "
    "(deterministic, as it tests), averaged over the run seeds",
}


def preset_settings(
    declared: Declared, task: TaskSettings, values: dict[str, Any]
) -> dict[str, Any]:
    """The settings tables of a preset: the study's fixed settings, the trial's, the sizes
    (checked: they build the run, or fracnetics' settings)."""
    sizes = {
        "population": declared.population,
        "generations": declared.generations,
        "steps": declared.steps,
    }
    if declared.brain == "fracnetics":
        settings = fracnetics_settings(declared, values).model_dump(mode="json")
        return {"fracnetics": settings, "training": sizes}
    run = gnp_config(declared, task, values, run_seeds(1)[0])
    run.gnp_config()
    controller = run.gnp_settings().controller
    brain = {"method": controller.method, "fuzzy": controller.fuzzy}  # named always
    merged = nested({f"controller.{k}": v for k, v in brain.items()} | declared.run_settings())
    for section, table in nested(values).items():
        merged.setdefault(section, {}).update(table)
    merged.setdefault("training", {}).update(sizes)
    merged = layout_2(merged)  # the study's names are layout 1's; a preset is written in 2
    order = ("brain", "training")
    tables = {s: merged[s] for s in (*order, *sorted(set(merged) - set(order))) if s in merged}
    protocol = run.training.model_dump(include=set(EpisodeProtocol.model_fields))
    bounds = {k: v for k, v in declared.task_settings().items() if k not in protocol}
    return {**tables, "task": protocol | bounds}  # `train --preset` takes both


def write_study_preset(
    study: optuna.Study,
    declared: Declared,
    task: TaskSettings,
    storage: Path,
    out: Path,
    trials: int,
) -> TuningRecord:
    """Write the preset of a finished study's best trial to `out`.

    Raises:
        TuneError: no trial completed (every one pruned).
    """
    import optuna
    from optuna.trial import TrialState

    from app.store.schema import package_version

    done = finished(study)
    complete = [t for t in done if t.state == TrialState.COMPLETE]
    if not complete:
        raise TuneError(f"study {declared.name!r}: no trial completed; nothing to write")
    best = max(complete, key=lambda t: (float(t.value or 0.0), -t.number))
    values = json.loads(best.user_attrs["settings"])
    record = TuningRecord(
        task=declared.task,
        brain=declared.brain,
        study=declared.name,
        storage=str(storage),
        trials=max(trials, len(done)),  # a study run on past its --trials keeps them all
        complete=len(complete),
        pruned=len(done) - len(complete),
        best_trial=best.number,
        best_value=float(best.value or 0.0),
        objective=OBJECTIVE[declared.brain],
        budget_env_steps=declared.budget,
        population=declared.population,
        generations=declared.generations,
        steps=declared.steps,
        run_seeds=list(run_seeds(declared.seeds)),
        validation_first_seed=FIRST_VALIDATION_SEED,
        validation_episodes=declared.validation,
        sampler=f"TPESampler(n_startup_trials={STARTUP_TRIALS}), seeded per trial",
        sampler_seed=declared.sampler_seed,
        pruner=f"MedianPruner(n_startup_trials={PRUNE_STARTUP_TRIALS}, "
        f"n_warmup_steps={declared.generations // 3})",
        optuna_version=optuna.__version__,
        gnp_lab_version=package_version(),
        written=now(),
    )
    write_preset(out, record, preset_settings(declared, task, values))
    return record
