"""The nets' configs and their inputs and outputs, without numba: the lab's settings and its run
lists use them at start-up; `neuro.nets` steps them (and re-exports these names)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

#: Inputs (IR sensors) and outputs (wheels: left, right) of every net: the robot's
#: (`sim.N_SENSORS`, two wheels). neuro does not import sim, so it keeps its own copy;
#: tests/app/design/test_sim_gnp_boundary.py ties the two.
N_INPUTS = 8
N_OUTPUTS = 2


class NeuroError(ValueError):
    """Bad input to the neuro package (a config, an array, an argument)."""


class ElmanConfig(BaseModel):
    """An Elman net: h_t = tanh(W_in x_t + W_rec h_{t−1} + b_h), y_t = tanh(W_out h_t + b_out)."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    kind: Literal["elman"] = "elman"
    hidden: int = Field(default=8, ge=1, le=64, description="hidden (context) units")

    def shapes(self) -> dict[str, tuple[int, ...]]:
        """Each array's shape without the batch axis, in flat-vector order."""
        h = self.hidden
        return {
            "w_in": (h, N_INPUTS),
            "w_rec": (h, h),
            "b_h": (h,),
            "w_out": (N_OUTPUTS, h),
            "b_out": (N_OUTPUTS,),
        }

    @property
    def n_params(self) -> int:
        """Length of the flat weight vector an optimiser searches."""
        return sum(int(np.prod(s)) for s in self.shapes().values())

    @property
    def n_units(self) -> int:
        """Activations carried between steps (the context units)."""
        return self.hidden


class RecurrentConfig(BaseModel):
    """NEAT's recurrent net (neat-python's `RecurrentNetwork`), densely padded.

    Units 0, 1 are the output nodes, then up to `max_hidden` hidden nodes. Every unit reads the
    current inputs and every unit's value of the previous step:
    v_t[j] = tanh(2.5 (bias_j + response_j Σ_k w_jk u_k)) if unit j has inputs, else 0.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")
    kind: Literal["recurrent"] = "recurrent"
    max_hidden: int = Field(default=32, ge=0, le=256, description="hidden node capacity")

    @property
    def n_units(self) -> int:
        return N_OUTPUTS + self.max_hidden

    def shapes(self) -> dict[str, tuple[int, ...]]:
        m = self.n_units
        return {"weights": (m, N_INPUTS + m), "bias": (m,), "response": (m,), "active": (m,)}


NetConfig = ElmanConfig | RecurrentConfig
