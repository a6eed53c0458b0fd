"""Brain families behind one contract: GNP (RL/BS/CS), neural nets (Elman + CMA-ES, NEAT) and any
family registered from outside (docs/brains.md).

    from app.brains import BrainFamily, register

    class Vehicle(BrainFamily): ...
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

__all__ = [
    "BUILT_IN",
    "PLUGINS_VARIABLE",
    "BrainFamily",
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
