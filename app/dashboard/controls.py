"""Validation of what a user types or picks in the dashboard's controls.

Every function raises `DashboardInputError` with a message fit to show on the page; the
dashboard shows it and changes nothing.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gnp
import sim
from app import store
from app.config import PRESET_NAMES, ConfigError, RunConfig, build_config, preset_layer
from app.live import LiveError, check_mode, check_sensors

NO_RUNS = "(none)"
"""What a list of runs offers when the runs dir holds none."""


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
    """Sensors typed as `2,3` or `s2 s3` → (2, 3).

    Raises:
        DashboardInputError: empty, not numbers, or not sensors.
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
    try:
        return check_sensors(sensors)
    except LiveError as error:
        raise DashboardInputError(str(error)) from None


def parse_mode(mode: str) -> str:
    try:
        return check_mode(mode)
    except LiveError as error:
        raise DashboardInputError(str(error)) from None


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


@dataclass(frozen=True)
class TrainingRequest:
    """The Train tab's fields, as typed."""

    preset: str
    method: str
    judgment: str  # "fuzzy" | "crisp"
    population: float
    generations: float
    steps: float
    noise_sigma: float
    seed: float


def training_config(request: TrainingRequest) -> RunConfig:
    """The run configuration the Train tab describes: the preset overridden by the fields.

    Raises:
        DashboardInputError: naming the field and its allowed range.
    """
    if request.preset not in PRESET_NAMES:
        raise DashboardInputError(f"unknown preset {request.preset!r}")
    if request.method not in gnp.METHODS:
        methods = ", ".join(gnp.METHODS)
        raise DashboardInputError(f"method must be one of {methods}, got {request.method!r}")
    if request.judgment not in ("fuzzy", "crisp"):
        raise DashboardInputError(f"judgment must be fuzzy or crisp, got {request.judgment!r}")
    overrides: dict[str, Any] = {
        "seed": whole(request.seed, "seed", 0, 2**31 - 1),
        "controller": {"method": request.method, "fuzzy": request.judgment == "fuzzy"},
        "training": {
            "population": whole(request.population, "population", 2, 100_000),
            "generations": whole(request.generations, "generations", 1, 1_000_000),
            "steps": whole(request.steps, "steps (life time T)", 1, 1_000_000),
            "noise_sigma": finite(request.noise_sigma, "noise σ", 0.0, sim.IR_MAX),
        },
    }
    try:
        return build_config(preset_layer(request.preset), overrides, source="the Train tab")
    except ConfigError as error:
        raise DashboardInputError(str(error)) from None
