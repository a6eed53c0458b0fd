"""Loading an experiment: a TOML file or a shipped one, parsed and validated, every arm ×
condition × scale config built; a bad one raises `ExperimentError` with one line."""

from __future__ import annotations

from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from app.experiments.spec import ExperimentError, ExperimentSpec
from app.settings.config import ConfigError, preset_layer
from app.settings.loading import build_config, describe_problems
from app.settings.user_files import loads_toml, read_text

SHIPPED_PACKAGE = "app.experiments.shipped"


def _one_line(error: ValidationError, source: str) -> str:
    return f"invalid experiment {source}: {describe_problems(error, limit=1)}"


def parse(data: Mapping[str, Any], source: str) -> ExperimentSpec:
    """Validate an experiment's dict, including every arm × condition × scale config.

    Raises:
        ExperimentError: one line naming the problem.
    """
    try:
        spec = ExperimentSpec.model_validate(data)
    except ValidationError as error:
        raise ExperimentError(_one_line(error, source)) from None
    for arm in spec.arms:  # each overlay as written, before a scale can mask a bad value
        try:
            build_config(preset_layer(spec.preset), spec.config, arm.config)
        except ConfigError as error:
            message = f"invalid experiment {source}: arm {arm.name!r}: {error}"
            raise ExperimentError(message.replace("\n", " ")) from None
    for scale in spec.scales:
        shapes: dict[str, tuple[int, int]] = {}
        for arm in spec.arms:
            where = f"invalid experiment {source}: arm {arm.name!r} at scale {scale!r}"
            try:
                run = spec.run_config(arm.name, scale, 0)
            except ConfigError as error:
                raise ExperimentError(f"{where}: {error}".replace("\n", " ")) from None
            for condition in spec.conditions:
                try:
                    settings = spec.condition_settings(condition, run, scale)
                except ConfigError as error:
                    message = f"{where}, condition {condition.name!r}: {error}"
                    raise ExperimentError(message.replace("\n", " ")) from None
                shape = shapes.setdefault(condition.name, (settings.steps, settings.fault_step))
                if shape != (settings.steps, settings.fault_step):
                    raise ExperimentError(
                        f"{where}, condition {condition.name!r}: steps and fault_step must be "
                        f"the same for every arm (the first arm's are {shape})"
                    )
        spec.check_control(scale)
        _check_fracnetics(spec, scale, source)
    return spec


def _check_fracnetics(spec: ExperimentSpec, scale: str, source: str) -> None:
    """A fracnetics arm's settings are fracnetics', and its population holds its tournament
    (else fracnetics never returns)."""
    if spec.task is None:
        return
    from app.tasks.common import TaskError
    from app.tasks.fracnetics_arm import arm_settings, check_population

    for arm in spec.arms:
        if arm.brain == "fracnetics":
            population = spec.run_config(arm.name, scale, 0).training.population
            try:
                check_population(arm_settings(spec.task.id, arm.fracnetics), population)
            except TaskError as error:
                where = f"invalid experiment {source}: arm {arm.name!r} at scale {scale!r}"
                raise ExperimentError(f"{where}: {error}") from None


def load_file(path: str | Path) -> ExperimentSpec:
    """An experiment TOML file (a regular file of at most `MAX_TEXT_BYTES`).

    Raises:
        ExperimentError: missing, not a regular file, too large, not TOML or not valid.
    """
    what = "experiment file"
    text = read_text(path, ExperimentError, what)
    return parse(loads_toml(text, ExperimentError, f"{what} {path}"), str(path))


def shipped_names() -> tuple[str, ...]:
    """Names of the experiments shipped in the package."""
    files = resources.files(SHIPPED_PACKAGE).iterdir()
    return tuple(sorted(f.name.removesuffix(".toml") for f in files if f.name.endswith(".toml")))


def load_shipped(name: str) -> ExperimentSpec:
    """A shipped experiment by name."""
    if name not in shipped_names():
        raise ExperimentError(
            f"no shipped experiment named {name!r}; choose one of {', '.join(shipped_names())} "
            "or give --file"
        )
    text = resources.files(SHIPPED_PACKAGE).joinpath(f"{name}.toml").read_text(encoding="utf-8")
    return parse(loads_toml(text, ExperimentError, f"shipped experiment {name!r}"), f"{name!r}")
