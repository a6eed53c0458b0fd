"""The world: arenas, the Khepera I model, physics (pymunk or analytic), IR sensors, noise,
faults, reward.

The constants below are the world's facts; `app` imports them rather than re-typing them.

The package is lazy (PEP 562): `import sim` imports no submodule; `sim.World` imports
`sim.world` (and numba's kernels) on first use, `sim.IR_MAX` only `sim.khepera`, so the lab's
settings and its command line start without compiling anything. `_HOMES` names each public
name's module; the imports under `TYPE_CHECKING` say the same to the type checker.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sim.arena import ARENA_NAMES, N_START_POSES, Arena, ArenaError, load_arena
    from sim.check import check_world
    from sim.faults import FAULT_MODES, Fault, FaultMode, WorldError
    from sim.khepera import (
        BODY_RADIUS_MM,
        CONTROL_PERIOD_S,
        IR_MAX,
        IR_RANGE_MM,
        LIFE_STEPS,
        MAX_COMMAND,
        N_SENSORS,
        N_WHEELS,
    )
    from sim.kinds import (
        DEFAULT_NOISE_STREAM,
        DEFAULT_PHYSICS,
        NOISE_STREAMS,
        PHYSICS,
        TERM_NAMES,
        NoiseStream,
        Physics,
    )
    from sim.reward import reward_table, reward_terms
    from sim.sensors import WallGrid, ir_readings, sensor_rays
    from sim.world import World

__all__ = [
    "ARENA_NAMES",
    "BODY_RADIUS_MM",
    "CONTROL_PERIOD_S",
    "DEFAULT_NOISE_STREAM",
    "DEFAULT_PHYSICS",
    "FAULT_MODES",
    "IR_MAX",
    "IR_RANGE_MM",
    "LIFE_STEPS",
    "MAX_COMMAND",
    "NOISE_STREAMS",
    "N_SENSORS",
    "N_START_POSES",
    "N_WHEELS",
    "PHYSICS",
    "TERM_NAMES",
    "Arena",
    "ArenaError",
    "Fault",
    "FaultMode",
    "NoiseStream",
    "Physics",
    "WallGrid",
    "World",
    "WorldError",
    "check_world",
    "ir_readings",
    "load_arena",
    "reward_table",
    "reward_terms",
    "sensor_rays",
]

_HOMES = {
    "arena": ("ARENA_NAMES", "N_START_POSES", "Arena", "ArenaError", "load_arena"),
    "check": ("check_world",),
    "faults": ("FAULT_MODES", "Fault", "FaultMode", "WorldError"),
    "khepera": (
        "BODY_RADIUS_MM",
        "CONTROL_PERIOD_S",
        "IR_MAX",
        "IR_RANGE_MM",
        "LIFE_STEPS",
        "MAX_COMMAND",
        "N_SENSORS",
        "N_WHEELS",
    ),
    "kinds": (
        "DEFAULT_NOISE_STREAM",
        "DEFAULT_PHYSICS",
        "NOISE_STREAMS",
        "PHYSICS",
        "TERM_NAMES",
        "NoiseStream",
        "Physics",
    ),
    "reward": ("reward_table", "reward_terms"),
    "sensors": ("WallGrid", "ir_readings", "sensor_rays"),
    "world": ("World",),
}
"""Each submodule → the public names it gives the package."""
_HOME = {name: module for module, names in _HOMES.items() for name in names}
_SUBMODULES = frozenset(
    {
        *_HOMES,
        "analytic",
        "drive",
        "gym_env",
        "gym_vector",
        "kernel_cache",
        "loop",
        "noise",
        "rays",
        "spaces",
    }
)

if not TYPE_CHECKING:  # the type checker reads the imports above; an unknown name stays an error

    def __getattr__(name: str) -> object:
        """A public name (or a submodule) on first use: its module imported, the name kept."""
        if name in _HOME:
            value = getattr(importlib.import_module(f"{__name__}.{_HOME[name]}"), name)
        elif name in _SUBMODULES:
            value = importlib.import_module(f"{__name__}.{name}")
        else:
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
        globals()[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*globals(), *__all__, *_SUBMODULES})
