"""numba's cache against sim/khepera.py: a kernel module recompiles when its cache is stale.

numba freezes module globals (the Khepera constants) into its cached machine code and only
invalidates the cache when the kernel's own file changes, not sim/khepera.py. So each kernel
module (``sim.rays``, ``sim.drive``, ``sim.noise``) caches a copy of ``KHEPERA_CONSTANTS`` beside
its kernels and, at import, hands it to ``drop_stale_cache`` (docs/decisions.md, "numba
caching").
"""

from collections.abc import Callable, Mapping

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


def drop_stale_cache(kernels: Mapping[str, object], frozen: Callable[[], np.ndarray]) -> None:
    """Recompile every kernel of a module if numba's cache holds old sim/khepera.py constants.

    Recompiling a dispatcher flushes its cache, so every kernel compiles afresh, with today's
    constants, on its first call (and caches that).

    Args:
        kernels: The module's globals.
        frozen: The module's cached function returning ``KHEPERA_CONSTANTS``.
    """
    if np.array_equal(frozen(), KHEPERA_CONSTANTS):
        return
    for kernel in list(kernels.values()):
        if isinstance(kernel, Dispatcher):
            kernel.recompile()
    if not np.array_equal(frozen(), KHEPERA_CONSTANTS):
        raise RuntimeError("numba still runs old sim/khepera.py constants after recompiling")
