"""The nets' configs and their inputs and outputs, without numba: the lab's settings and its run
lists use them at start-up; `neuro.nets` steps them (and re-exports these names)."""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

#: Inputs (IR sensors) and outputs (wheels: left, right) of the robot: a net config's default
#: sizes (`sim.N_SENSORS`, two wheels). neuro does not import sim, so it keeps its own copy;
#: tests/app/design/test_sim_gnp_boundary.py ties the two.
N_INPUTS = 8
N_OUTPUTS = 2
#: The most inputs or outputs a net may have.
MAX_WIDTH = 256


def _width(default: int, what: str) -> Any:
    """A config's input or output count: 1 to `MAX_WIDTH`, the robot's by default and then left
    out of dumps, so a robot net's JSON (controller files, stored configs) is as it was."""
    return Field(
        default=default,
        ge=1,
        le=MAX_WIDTH,
        description=f"{what} (the robot's: {default})",
        exclude_if=lambda value: value == default,
    )


class NeuroError(ValueError):
    """Bad input to the neuro package (a config, an array, an argument)."""


class ElmanConfig(BaseModel):
    """An Elman net: h_t = tanh(W_in x_t + W_rec h_{t−1} + b_h), y_t = tanh(W_out h_t + b_out),
    with `n_inputs` inputs x_t, `hidden` units h_t and `n_outputs` outputs y_t."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    kind: Literal["elman"] = "elman"
    hidden: int = Field(default=8, ge=1, le=64, description="hidden (context) units")
    n_inputs: int = _width(N_INPUTS, "inputs")
    n_outputs: int = _width(N_OUTPUTS, "outputs")

    def shapes(self) -> dict[str, tuple[int, ...]]:
        """Each array's shape without the batch axis, in flat-vector order."""
        h = self.hidden
        return {
            "w_in": (h, self.n_inputs),
            "w_rec": (h, h),
            "b_h": (h,),
            "w_out": (self.n_outputs, h),
            "b_out": (self.n_outputs,),
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

    Units 0 … n_outputs − 1 are the output nodes, then up to `max_hidden` hidden nodes. Every
    unit reads the `n_inputs` current inputs and every unit's value of the previous step:
    v_t[j] = tanh(2.5 (bias_j + response_j Σ_k w_jk u_k)) if unit j has inputs, else 0.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")
    kind: Literal["recurrent"] = "recurrent"
    max_hidden: int = Field(default=32, ge=0, le=256, description="hidden node capacity")
    n_inputs: int = _width(N_INPUTS, "inputs")
    n_outputs: int = _width(N_OUTPUTS, "outputs")

    @property
    def n_units(self) -> int:
        return self.n_outputs + self.max_hidden

    def shapes(self) -> dict[str, tuple[int, ...]]:
        m = self.n_units
        return {"weights": (m, self.n_inputs + m), "bias": (m,), "response": (m,), "active": (m,)}


NetConfig = ElmanConfig | RecurrentConfig
