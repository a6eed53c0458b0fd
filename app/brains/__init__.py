"""Brain families behind one contract: GNP (RL/BS/CS), neural nets (Elman + CMA-ES, NEAT) and any
family registered from outside (docs/brains.md).

    from app.brains import BrainFamily, BrainSettings, check_family, register

    class VehicleSettings(BrainSettings): ...  # the run config's `brain` section
    class Vehicle(BrainFamily):
        name = "vehicle"
        settings_model = VehicleSettings
    register(Vehicle)
    check_family(Vehicle)  # in its tests: every problem, named
"""

from app.brains.conformance import FamilyCheckError, check_family
from app.brains.contract import (
    BrainFamily,
    Evolution,
    NoTracer,
    SecondStage,
    TerminalLearner,
    Tracer,
)
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
    "FamilyCheckError",
    "NoTracer",
    "SecondStage",
    "TerminalLearner",
    "Tracer",
    "check_family",
    "family_class",
    "family_of",
    "load_controller",
    "names",
    "register",
    "register_controller_format",
    "run_kind",
]
