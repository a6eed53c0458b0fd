"""GNP Lab's second brain family: batched neural controllers and their optimisers.

Like `gnp`, this package imports neither `sim` nor `app`: nets take inputs in [0, 1] and give
outputs in [−1, 1]; `app` scales IR readings and wheel commands. The optimisers wrap their own
libraries (CMA-ES: pycma, `neuro.cmaes`; NEAT: neat-python, `neuro.neat`) and keep every random
draw in a seeded state of their own. See docs/architecture.md.
"""

from neuro.controller_file import net_body, net_from_body
from neuro.nets import (
    N_INPUTS,
    N_OUTPUTS,
    ElmanConfig,
    NetConfig,
    NeuroError,
    RecurrentConfig,
    check_arrays,
    concat,
    field_dtype,
    from_flat,
    init_state,
    step,
    take,
    to_flat,
    zeros,
)

__all__ = [
    "N_INPUTS",
    "N_OUTPUTS",
    "ElmanConfig",
    "NetConfig",
    "NeuroError",
    "RecurrentConfig",
    "check_arrays",
    "concat",
    "field_dtype",
    "from_flat",
    "init_state",
    "net_body",
    "net_from_body",
    "step",
    "take",
    "to_flat",
    "zeros",
]
