"""Sensor faults: the modes, a scheduled ``Fault``, and the checks of sensor indices and modes
that the world shares; ``WorldError`` is the world's one error, bad input named in one line."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal, cast, get_args

import numpy as np

from sim.khepera import N_SENSORS

FaultMode = Literal["dead", "saturated", "stuck", "random"]
FAULT_MODES: tuple[FaultMode, ...] = get_args(FaultMode)
"""Fault modes; their codes in ``World.fault_modes`` are 1..4 in this order (0 = healthy)."""

FAULT_CODES: dict[FaultMode, int] = {mode: code for code, mode in enumerate(FAULT_MODES, 1)}
"""Each fault mode's code in ``World.fault_modes``: 1 + its index in ``FAULT_MODES``. The noise
kernels compare against the codes below, which numba freezes into its cache (``sim.noise``
checks them at import, see ``sim.kernel_cache``)."""
HEALTHY_CODE = 0
"""The code of a sensor that works."""
DEAD_CODE = FAULT_CODES["dead"]
SATURATED_CODE = FAULT_CODES["saturated"]
STUCK_CODE = FAULT_CODES["stuck"]
RANDOM_CODE = FAULT_CODES["random"]


class WorldError(ValueError):
    """Bad input to a ``World`` (shapes, ranges, sensor or robot indices, fault modes)."""


@dataclass(frozen=True)
class Fault:
    """A scheduled sensor fault.

    Attributes:
        step: The world step (``world.t``) at which the sensors break.
        sensors: Sensor indices 0..7.
        mode: ``dead`` (reads 0), ``saturated`` (1023), ``stuck`` (keeps the value it showed when
            it broke) or ``random`` (uniform in 0..1023 each step).
        robots: Robot indices, or None for every robot.
    """

    step: int
    sensors: tuple[int, ...]
    mode: FaultMode = "dead"
    robots: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if isinstance(self.step, bool) or not isinstance(self.step, int | np.integer):
            raise WorldError(f"Fault.step must be an int, got {self.step!r}")
        if self.step < 0:
            raise WorldError(f"Fault.step must be ≥ 0, got {self.step}")
        object.__setattr__(self, "sensors", tuple(int(s) for s in check_sensors(self.sensors)))
        mode_code(self.mode)
        if self.robots is not None:
            object.__setattr__(self, "robots", tuple(int(r) for r in self.robots))


def check_sensors(sensors: int | Iterable[int]) -> np.ndarray:
    """Sensor indices as an int64 array; a ``WorldError`` unless each is in 0..7."""
    items = [sensors] if isinstance(sensors, int | np.integer) else list(sensors)
    if not items:
        raise WorldError("no sensors given: expected indices in 0..7")
    for s in items:
        if isinstance(s, bool) or not isinstance(s, int | np.integer) or not 0 <= s < N_SENSORS:
            raise WorldError(f"sensor index {s!r} is not in 0..{N_SENSORS - 1}")
    return np.array(items, dtype=np.int64)


def mode_code(mode: str) -> int:
    """A fault mode's code in ``World.fault_modes`` (1..4); a ``WorldError`` for an unknown one."""
    if mode not in FAULT_CODES:
        raise WorldError(f"unknown fault mode {mode!r}: expected one of {', '.join(FAULT_MODES)}")
    return FAULT_CODES[cast(FaultMode, mode)]
