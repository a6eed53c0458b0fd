"""Validation of what a user types or picks in the dashboard's controls.

Every function raises `DashboardInputError` with a message fit to show on the page; the
dashboard shows it and changes nothing.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

import sim
from app import store
from app.brains.registry import family_class, family_of
from app.settings.config import DEFAULT_BRAIN, PRESET_NAMES, ConfigError, RunConfig, preset_layer
from app.settings.fields import nested
from app.settings.loading import build_config, describe_problems

NO_RUNS = "(none)"
"""What a list of runs offers when the runs dir holds none."""

M = TypeVar("M", bound=BaseModel)


class DashboardInputError(ValueError):
    """A control holds a value the dashboard cannot use; the message says which and why."""


def open_run(runs_dir: Path, name: str) -> store.RunReader:
    """The run picked in a list of runs, opened for reading.

    Raises:
        DashboardInputError: the list is empty.
        RunFileError: the run is missing or unreadable.
    """
    if name == NO_RUNS:
        raise DashboardInputError(f"no runs in {runs_dir}")
    return store.RunReader(store.resolve_run(runs_dir, name))


def parse_sensors(text: str) -> tuple[int, ...]:
    """Sensors typed as `2,3` or `s2 s3` → (2, 3); which sensors exist is the world's to say
    (`sim.WorldError`) or the settings' (`ImplementationSettings.broken_sensors`).

    Raises:
        DashboardInputError: empty, or not numbers.
    """
    tokens = [t for t in re.split(r"[,\s;]+", text.strip()) if t]
    if not tokens:
        raise DashboardInputError("choose at least one sensor to break, e.g. 2,3")
    sensors = []
    for token in tokens:
        digits = token.lower().removeprefix("s")
        if not digits.isdigit():
            raise DashboardInputError(
                f"sensors are numbers 0..{sim.N_SENSORS - 1} separated by commas, got {token!r}"
            )
        sensors.append(int(digits))
    return tuple(sorted(set(sensors)))


def finite(value: float, name: str, low: float, high: float) -> float:
    """`value` as a float within [low, high]."""
    if not isinstance(value, int | float) or not math.isfinite(value) or not low <= value <= high:
        raise DashboardInputError(f"{name} must be a number in {low:g}..{high:g}, got {value!r}")
    return float(value)


def whole(value: float, name: str, low: int, high: int) -> int:
    """`value` as an int within [low, high] (a float must be integral)."""
    if not isinstance(value, int | float) or not math.isfinite(value) or value != int(value):
        raise DashboardInputError(f"{name} must be a whole number, got {value!r}")
    if not low <= int(value) <= high:
        raise DashboardInputError(f"{name} must be in {low}..{high}, got {int(value)}")
    return int(value)


def training_config(
    preset: str, values: Mapping[tuple[str, ...], Any], brain: str = DEFAULT_BRAIN
) -> RunConfig:
    """The run the Train tab describes: `preset` with the brain family `brain`, overridden by
    what its controls hold ({setting path: value}; those of the brain are GNP's, used when it
    is GNP), checked once by building the model (and by binding the family).

    Raises:
        DashboardInputError: naming each bad setting and what it allows, or the family.
    """
    if preset not in PRESET_NAMES:
        raise DashboardInputError(f"unknown preset {preset!r}")
    try:
        selection = family_class(brain).selection()
        if brain != DEFAULT_BRAIN:  # the controls' brain settings are another family's
            values = {path: v for path, v in values.items() if path[0] != "brain"}
        layers = (preset_layer(preset), selection, nested(dict(values)))
        config = build_config(*layers, source="the Train tab")
        family_of(config)  # its own settings, checked before any process starts
        return config
    except ConfigError as error:
        raise DashboardInputError(str(error)) from None


def build(model: type[M], values: Mapping[str, Any], where: str) -> M:
    """`model` built from `values` (what the page's controls hold).

    Raises:
        DashboardInputError: the model's message, one line naming each bad field.
    """
    try:
        return model.model_validate(dict(values))
    except ValidationError as error:
        raise DashboardInputError(f"{where}: {describe_problems(error)}") from None
