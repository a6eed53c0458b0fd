"""Warm Dask workers: numba's kernels loaded and the lab imported when a worker starts.

A cold worker spends its first task's first seconds importing the lab and loading numba's
compiled kernels (compiling them, if the cache is cold). `WarmWorkers`, registered on a client
once the client process has filled numba's cache (`app.experiments.cluster.warm_numba`; workers
compiling the same cache at once can race, numba#4807), has every worker, present and future,
live a tiny run of each controller at start, so no task pays for it.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

from distributed import WorkerPlugin
from typing_extensions import override  # typing.override from Python 3.12 on

from app.brains.registry import family_of
from app.phases.warm import warm_up
from app.settings.config import RunConfig

__all__ = ["WarmWorkers", "controllers", "warm_up"]


def _kernels(config: RunConfig) -> str:
    """What decides which kernels a run calls: its brain (`BrainFamily.warm_key`) and its
    physics."""
    return json.dumps(family_of(config).warm_key(), sort_keys=True) + config.training.physics


def controllers(configs: list[RunConfig]) -> list[RunConfig]:
    """One config per distinct brain and physics (what decides which kernels run)."""
    unique = {_kernels(c): c for c in configs}
    return list(unique.values())


class WarmWorkers(WorkerPlugin):
    """A worker plugin: `warm_up(configs)` when a worker starts (or joins later)."""

    def __init__(self, configs: list[RunConfig]) -> None:
        self.configs = controllers(configs)
        digest = hashlib.sha256("".join(_kernels(c) for c in self.configs).encode()).hexdigest()[
            :12
        ]
        self.name = f"gnp-lab-warm-{digest}"  # one registration per set of controllers

    @override
    def setup(self, worker: Any) -> None:
        warm_up(self.configs)
