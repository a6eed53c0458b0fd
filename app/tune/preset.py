"""The preset a study writes, and reading one back for `gnp-lab train --preset FILE`.

A tuned preset is a TOML file of data only: the settings tables a config file has
(`[brain.controller]`, `[brain.evolution]`, `[training]`; a fracnetics study's `[fracnetics]`;
a preset written before issue #46, such as those shipped in app/experiments/shipped/tuned/,
has `[controller]` and `[evolution]`, moved when read as any layer is) and a
`[tuning]` table recording the study it came from (task, brain, seeds, trials, budget, best
value, Optuna's version, the sampler and its seed).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from app.tune.space import Brain

if TYPE_CHECKING:
    from app.tasks.common import EpisodeProtocol


class TuningRecord(BaseModel):
    """The `[tuning]` table: the study a preset came from."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    task: str = Field(description="the Gymnasium task tuned on")
    brain: Brain = Field(description="gnp or fracnetics")
    study: str = Field(description="the study's name in its storage")
    storage: str = Field(description="the study's storage file (Optuna RDB, SQLite)")
    trials: int = Field(ge=1, description="trials declared and finished (complete or pruned)")
    complete: int = Field(ge=1, description="trials complete")
    pruned: int = Field(ge=0, description="trials pruned")
    best_trial: int = Field(ge=0, description="the best trial's number")
    best_value: float = Field(description="its mean validation return")
    objective: str = Field(description="what a trial's value is")
    budget_env_steps: int = Field(ge=1, description="env-steps one training run may spend")
    population: int = Field(ge=2)
    generations: int = Field(ge=1, description="generations the budget holds")
    steps: int = Field(ge=1, description="a life's cap")
    run_seeds: list[int] = Field(min_length=1, description="each trial's training run seeds")
    validation_first_seed: int = Field(ge=0)
    validation_episodes: int = Field(ge=1)
    sampler: str
    sampler_seed: int = Field(ge=0)
    pruner: str
    optuna_version: str
    gnp_lab_version: str
    written: str = Field(description="when, UTC")


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    return repr(value)  # ints, and floats (nan, inf and -inf as TOML writes them)


def _table(lines: list[str], name: str, values: dict[str, Any]) -> None:
    if not values or any(not isinstance(v, dict) for v in values.values()):
        lines.append(f"\n[{name}]")  # a table of tables only (`[brain]`) is implied
    subtables = []
    for key, value in values.items():
        if isinstance(value, dict):
            subtables.append((key, value))
        elif value is not None:
            lines.append(f"{key} = {_value(value)}")
    for key, value in subtables:
        _table(lines, f"{name}.{key}", value)


def preset_text(record: TuningRecord, settings: dict[str, Any]) -> str:
    """The preset's TOML: a comment, `[tuning]`, then the settings' tables."""
    lines = [
        f"# Tuned by `gnp-lab tune` on {record.task} ({record.brain}): study {record.study!r},",
        f"# best of {record.trials} trials, mean validation return {record.best_value:.4g}.",
        f"# gnp-lab train --task {record.task} --preset FILE"
        if record.brain == "gnp"
        else "# fracnetics' settings: an experiment arm's (docs/tasks.md, Tuning)",
    ]
    _table(lines, "tuning", record.model_dump())
    for section, values in settings.items():
        _table(lines, section, values)
    return "\n".join(lines) + "\n"


def write_preset(path: Path, record: TuningRecord, settings: dict[str, Any]) -> None:
    """Write the preset whole (a temporary file renamed into place)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(preset_text(record, settings), encoding="utf-8")
    tmp.replace(path)


def now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def read_preset(path: str | Path) -> tuple[dict[str, Any], TuningRecord | None]:
    """A preset file's settings layer and its `[tuning]` record (None: a plain config file).

    Raises:
        ConfigError: not a readable TOML file, or its `[tuning]` table is invalid (one line).
    """
    from app.settings.config import ConfigError
    from app.settings.loading import read_toml

    layer = read_toml(path)
    tuning = layer.pop("tuning", None)
    if tuning is None:
        return layer, None
    if not isinstance(tuning, dict):
        raise ConfigError(f"preset {path}: [tuning] must be a table")
    try:
        record = TuningRecord.model_validate(tuning)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise ConfigError(f"preset {path}: [tuning] {where}: {first['msg']}") from None
    return layer, record


def train_layer(path: str, task: str | None) -> dict[str, Any]:
    """`gnp-lab train --preset FILE`: the settings of a preset file; a tuned one must be
    GNP's and trained on the task it was tuned on.

    Raises:
        ConfigError: a missing or invalid file, a fracnetics preset, another task.
    """
    from app.settings.config import ConfigError

    layer, record = read_preset(path)
    layer.pop("task", None)  # a tuned run's episode protocol: `train_protocol`
    if record is None:
        return layer
    if record.brain != "gnp":
        raise ConfigError(
            f"preset {path} holds fracnetics' settings: its [fracnetics] table is a task "
            "experiment's fracnetics arm's `fracnetics` table, not a GNP run's"
        )
    if task is None:
        raise ConfigError(f"preset {path} was tuned on {record.task}: give --task {record.task}")
    if task != record.task:
        raise ConfigError(
            f"preset {path} was tuned on {record.task}, not {task}: tune {task} first "
            f"(gnp-lab tune --task {task})"
        )
    return layer


def train_task_table(path: str) -> tuple[EpisodeProtocol | None, dict[str, Any]]:
    """A preset's `[task]` table: the episode protocol its runs were tuned with (None: none)
    and the task's bounds it was given (checked by `app.tasks.cli.task_settings`).

    Raises:
        ConfigError: an invalid table (one line).
    """
    from app.settings.config import ConfigError
    from app.tasks.common import EpisodeProtocol

    table = read_preset(path)[0].get("task")
    if table is None:
        return None, {}
    if not isinstance(table, dict):
        raise ConfigError(f"preset {path}: [task] must be a table")
    fields = EpisodeProtocol.model_fields
    bounds = {k: v for k, v in table.items() if k not in fields}
    try:
        return EpisodeProtocol.model_validate({k: table[k] for k in fields if k in table}), bounds
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise ConfigError(f"preset {path}: [task] {where}: {first['msg']}") from None
