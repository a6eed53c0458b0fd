"""Brain families behind one contract: GNP (RL/BS/CS), neural nets (Elman + CMA-ES, NEAT) and any
family registered from outside (docs/brains.md).

    from app.brains import BrainFamily, BrainSettings, register

    class VehicleSettings(BrainSettings): ...  # the run config's `brain` section
    class Vehicle(BrainFamily):
        settings_model = VehicleSettings
    register("vehicle", Vehicle)
"""

from app.brains.contract import BrainFamily, Evolution, NoTracer, Tracer
from app.brains.registry import (
    BUILT_IN,
    PLUGINS_VARIABLE,
    family_class,
    family_of,
    load_controller,
    names,
    register,
    register_controller_format,
    run_kind,
)
from app.settings.families import BrainSettings

__all__ = [
    "BUILT_IN",
    "PLUGINS_VARIABLE",
    "BrainFamily",
    "BrainSettings",
    "Evolution",
    "NoTracer",
    "Tracer",
    "family_class",
    "family_of",
    "load_controller",
    "names",
    "register",
    "register_controller_format",
    "run_kind",
]
