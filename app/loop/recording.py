"""Recorded lives in memory: what training's elite and implementation trials keep of a batch.

No HDF5 here: the store writes and reads `Trajectory` objects, the lab loop fills them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

import sim


@dataclass(frozen=True)
class Trajectory:
    """Recorded lives, leading axis = trials (1 for the training elite), then steps."""

    poses: np.ndarray  # (k, T, 3)
    readings: np.ndarray  # (k, T, 8) true readings after each step
    observations: np.ndarray  # (k, T, 8) what the controller saw before each step
    commands: np.ndarray  # (k, T, 2) left, right
    terms: dict[str, np.ndarray]  # term name -> (k, T)
    trace: dict[str, np.ndarray]  # trace field (its family's) -> (k, T, ...)
    start_index: np.ndarray  # (k,) start pose of each trial (first segment in training)

    @property
    def reward(self) -> np.ndarray:
        """(k, T) reward per step."""
        return self.terms["reward"]


#: What a step's trace holds: field -> (shape per controller, dtype).
TraceLayout = Mapping[str, tuple[tuple[int, ...], Any]]


LIFE_COLUMNS = {
    "poses": 3,
    "readings": sim.N_SENSORS,
    "observations": sim.N_SENSORS,
    "commands": 2,
    "terms": len(sim.TERM_NAMES),
}
"""The float64 columns a recorded life holds per step, beside its trace."""


def life_bytes(k: int, steps: int, layout: TraceLayout) -> int:
    """Memory `TrajectoryRecorder(k, steps, layout)` allocates."""
    per_step = 8 * sum(LIFE_COLUMNS.values()) + sum(
        int(np.prod(shape)) * np.dtype(dtype).itemsize for shape, dtype in layout.values()
    )
    return k * steps * per_step


class TrajectoryRecorder:
    """Fills a `Trajectory` of the first k robots of a batch, one step at a time.

    Both phases record lives this way, so a stored elite and stored implementation trials have
    the same arrays, dtypes and shapes. The trace's fields are the layout's (read off the
    step's trace object by name; a brain family gives its own, `BrainFamily.trace_layout`).
    """

    def __init__(self, k: int, steps: int, layout: TraceLayout) -> None:
        self.k = k
        self._t = 0  # the next step to record
        self._arrays = {name: np.zeros((k, steps, n)) for name, n in LIFE_COLUMNS.items()}
        self._trace = {
            field: np.zeros((k, steps, *shape), dtype) for field, (shape, dtype) in layout.items()
        }

    def record(
        self,
        poses: np.ndarray,
        readings: np.ndarray,
        observations: np.ndarray,
        commands: np.ndarray,
        term_table: np.ndarray,
        trace: Any,
    ) -> None:
        """The next step of the batch: arrays with a leading batch axis (`term_table`'s
        columns are `sim.TERM_NAMES`)."""
        k, t = self.k, self._t
        a = self._arrays
        a["poses"][:, t] = poses[:k]
        a["readings"][:, t] = readings[:k]
        a["observations"][:, t] = observations[:k]
        a["commands"][:, t] = commands[:k]
        a["terms"][:, t] = term_table[:k]
        for field, values in self._trace.items():
            values[:, t] = getattr(trace, field)[:k]
        self._t = t + 1

    def trajectory(self, start_index: np.ndarray) -> Trajectory:
        """The recorded lives; `start_index` (k,) is each life's (first) start pose."""
        a = self._arrays
        return Trajectory(
            poses=a["poses"],
            readings=a["readings"],
            observations=a["observations"],
            commands=a["commands"],
            terms={name: a["terms"][..., i] for i, name in enumerate(sim.TERM_NAMES)},
            trace=dict(self._trace),
            start_index=np.asarray(start_index[: self.k]).copy(),
        )
