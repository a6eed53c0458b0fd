"""numba's cache against the files it does not watch: a kernel module recompiles when its
cache is stale.

numba freezes module globals (the Khepera constants) into its cached machine code and only
invalidates the cache when the kernel's own file changes, not sim/khepera.py, nor the modules
whose kernels it calls (a kernel moved to another module leaves a cache that names the old one
and fails to load). So each kernel module caches a copy of what it depends on beside its
kernels, ``KHEPERA_CONSTANTS`` (``sim.rays``, ``sim.drive``; ``sim.noise`` adds the fault codes)
or the ``source_fingerprint`` of the modules it calls (``sim.analytic``, ``sim.loop``,
``app.loop.fused``), and at import hands it to ``drop_stale_cache`` (docs/decisions.md, "numba
caching").
"""

import hashlib
from collections.abc import Callable, Mapping
from pathlib import Path
from types import ModuleType

import numpy as np
from numba.core.dispatcher import Dispatcher

from sim.khepera import (
    AXLE_MM,
    BODY_RADIUS_MM,
    IR_BACKOFF_MM,
    IR_MAX,
    IR_RANGE_MM,
    MASS,
    MAX_COMMAND,
    MOMENT,
    N_SENSORS,
    SENSOR_HEADINGS_RAD,
    SENSOR_ORIGINS_MM,
    WHEEL_RADIUS_MM,
)

KHEPERA_CONSTANTS = np.concatenate(
    [
        np.array(
            [
                AXLE_MM,
                BODY_RADIUS_MM,
                IR_BACKOFF_MM,
                IR_MAX,
                IR_RANGE_MM,
                MASS,
                MAX_COMMAND,
                MOMENT,
                N_SENSORS,
                WHEEL_RADIUS_MM,
            ],
            dtype=np.float64,
        ),
        np.ravel(SENSOR_ORIGINS_MM),
        np.ravel(SENSOR_HEADINGS_RAD),
    ]
)
"""Every robot constant the kernels use, as one array. A kernel module returns a copy of it
from a function of its own compiled with ``cache=True``: that copy is what numba froze in."""


def source_fingerprint(*modules: ModuleType) -> np.ndarray:
    """The sha256 of `modules`' source files, as 32 uint8: what a module's cached kernels were
    compiled against (the modules whose kernels they call, and sim/khepera.py's constants)."""
    digest = hashlib.sha256()
    for module in modules:
        assert module.__file__ is not None
        digest.update(Path(module.__file__).read_bytes())
    return np.frombuffer(digest.digest(), np.uint8).copy()


def drop_stale_cache(
    kernels: Mapping[str, object],
    frozen: Callable[[], np.ndarray],
    expected: np.ndarray = KHEPERA_CONSTANTS,
) -> None:
    """Recompile every kernel of a module if numba's cache was compiled against other
    constants or other modules than today's.

    Recompiling a dispatcher flushes its cache, so every kernel compiles afresh on its first
    call (and caches that). Only `frozen` is loaded from the cache before: it calls nothing.

    Args:
        kernels: The module's globals.
        frozen: The module's cached function returning its copy of `expected`.
        expected: ``KHEPERA_CONSTANTS``, or the module's ``source_fingerprint``.
    """
    if np.array_equal(frozen(), expected):
        return
    for kernel in list(kernels.values()):
        if isinstance(kernel, Dispatcher):
            kernel.recompile()
    if not np.array_equal(frozen(), expected):
        raise RuntimeError("numba still runs a stale cache after recompiling")
