"""GNP Lab's brain: GNP-RL, Fuzzy GNP-RL and Fuzzy GNP-TSRL (BS, CS) controllers, batched.

See docs/architecture.md (the gnp section) for the contract and docs/decisions.md for the
choices the thesis leaves open.

The package is lazy (PEP 562): `import gnp` imports no submodule; `gnp.step` imports
`gnp.engine` (and numba's kernel) on first use, `gnp.GnpConfig` only `gnp.config`, so the lab's
settings and its command line start without compiling anything. `_HOMES` names each public
name's module; the imports under `TYPE_CHECKING` say the same to the type checker.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gnp.config import EvolutionConfig, GnpConfig, GnpError, Schedule, judgment_name
    from gnp.controller_file import controller_body, controller_from_body
    from gnp.engine import (
        TRACE_DTYPE,
        TRACE_FIELDS,
        VISIT_FIELDS,
        EngineState,
        StepResult,
        StepTrace,
        end_episode,
        init_state,
        reset_episode,
        step,
        trace_shapes,
    )
    from gnp.evolution import crossover, evolve, mutate, nonuniform_mutation, tournament
    from gnp.methods import METHODS, TRAITS, Method, MethodTraits
    from gnp.population import (
        Population,
        check_population,
        concat,
        field_dtype,
        field_shapes,
        init_population,
        population_from_arrays,
        population_to_arrays,
        take,
    )
    from gnp.schedules import (
        epsilon_alpha_after_fault,
        epsilon_alpha_over_generations,
        schedule_after_fault,
        schedule_over_generations,
    )

__all__ = [
    "METHODS",
    "TRACE_DTYPE",
    "TRACE_FIELDS",
    "TRAITS",
    "VISIT_FIELDS",
    "EngineState",
    "EvolutionConfig",
    "GnpConfig",
    "GnpError",
    "Method",
    "MethodTraits",
    "Population",
    "Schedule",
    "StepResult",
    "StepTrace",
    "check_population",
    "concat",
    "controller_body",
    "controller_from_body",
    "crossover",
    "end_episode",
    "epsilon_alpha_after_fault",
    "epsilon_alpha_over_generations",
    "evolve",
    "field_dtype",
    "field_shapes",
    "init_population",
    "init_state",
    "judgment_name",
    "mutate",
    "nonuniform_mutation",
    "population_from_arrays",
    "population_to_arrays",
    "reset_episode",
    "schedule_after_fault",
    "schedule_over_generations",
    "step",
    "take",
    "tournament",
    "trace_shapes",
]

_HOMES = {
    "config": ("EvolutionConfig", "GnpConfig", "GnpError", "Schedule", "judgment_name"),
    "controller_file": ("controller_body", "controller_from_body"),
    "engine": (
        "TRACE_DTYPE",
        "TRACE_FIELDS",
        "VISIT_FIELDS",
        "EngineState",
        "StepResult",
        "StepTrace",
        "end_episode",
        "init_state",
        "reset_episode",
        "step",
        "trace_shapes",
    ),
    "evolution": ("crossover", "evolve", "mutate", "nonuniform_mutation", "tournament"),
    "methods": ("METHODS", "TRAITS", "Method", "MethodTraits"),
    "population": (
        "Population",
        "check_population",
        "concat",
        "field_dtype",
        "field_shapes",
        "init_population",
        "population_from_arrays",
        "population_to_arrays",
        "take",
    ),
    "schedules": (
        "epsilon_alpha_after_fault",
        "epsilon_alpha_over_generations",
        "schedule_after_fault",
        "schedule_over_generations",
    ),
}
"""Each submodule → the public names it gives the package."""
_HOME = {name: module for module, names in _HOMES.items() for name in names}
_SUBMODULES = frozenset({*_HOMES, "kernel", "reference", "rng", "structure"})

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
