"""GNP Lab's second brain family: batched neural controllers and their optimisers.

Like `gnp`, this package imports neither `sim` nor `app`: nets take inputs in [0, 1] and give
outputs in [−1, 1]; `app` scales IR readings and wheel commands. The optimisers wrap their own
libraries (CMA-ES: pycma, `neuro.cmaes`; NEAT: neat-python, `neuro.neat`) and keep every random
draw in a seeded state of their own. See docs/architecture.md.

The package is lazy (PEP 562): `import neuro` imports no submodule; `neuro.step` imports
`neuro.nets` (and numba) on first use, `neuro.ElmanConfig` only `neuro.net_configs`, so the lab's
settings and its command line start without compiling anything. `_HOMES` names each public
name's module; the imports under `TYPE_CHECKING` say the same to the type checker.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from neuro.controller_file import net_body, net_from_body
    from neuro.net_configs import (
        N_INPUTS,
        N_OUTPUTS,
        ElmanConfig,
        NetConfig,
        NeuroError,
        RecurrentConfig,
    )
    from neuro.nets import (
        check_arrays,
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

_HOMES = {
    "controller_file": ("net_body", "net_from_body"),
    "net_configs": (
        "N_INPUTS",
        "N_OUTPUTS",
        "ElmanConfig",
        "NetConfig",
        "NeuroError",
        "RecurrentConfig",
    ),
    "nets": (
        "check_arrays",
        "field_dtype",
        "from_flat",
        "init_state",
        "step",
        "take",
        "to_flat",
        "zeros",
    ),
}
"""Each submodule → the public names it gives the package."""
_HOME = {name: module for module, names in _HOMES.items() for name in names}
_SUBMODULES = frozenset({*_HOMES, "cmaes", "neat_evolution", "neat_params"})

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
