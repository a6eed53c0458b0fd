"""GNP Lab's brain: GNP-RL, Fuzzy GNP-RL and Fuzzy GNP-TSRL (BS, CS) controllers, batched.

See docs/architecture.md (the gnp section) for the contract and docs/decisions.md for the
choices the thesis leaves open.
"""

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
