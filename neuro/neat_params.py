"""NEAT's settings, without neat-python or numba: the lab's run config imports them at start-up
(`neuro.neat_evolution` runs them and re-exports `NeatParams`)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from neuro.net_configs import N_INPUTS, N_OUTPUTS, RecurrentConfig


class NeatParams(BaseModel):
    """The NEAT settings we expose (the rest of the INI is fixed in `ini_text`).

    Defaults follow neat-python's own examples (e.g. its XOR config), with 2 elites per species.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")
    max_hidden: int = Field(
        default=32, ge=0, le=256, description="hidden nodes a genome may use (dense capacity)"
    )
    compatibility_threshold: float = Field(default=3.0, gt=0.0, le=100.0)
    conn_add_prob: float = Field(default=0.5, ge=0.0, le=1.0)
    conn_delete_prob: float = Field(default=0.5, ge=0.0, le=1.0)
    node_add_prob: float = Field(default=0.2, ge=0.0, le=1.0)
    node_delete_prob: float = Field(default=0.2, ge=0.0, le=1.0)
    weight_mutate_rate: float = Field(default=0.8, ge=0.0, le=1.0)
    weight_mutate_power: float = Field(default=0.5, ge=0.0, le=10.0)
    elitism: int = Field(default=2, ge=0, le=1000, description="elites kept per species")
    survival_threshold: float = Field(default=0.2, gt=0.0, le=1.0)
    max_stagnation: int = Field(default=20, ge=1, le=100_000)
    species_elitism: int = Field(default=2, ge=0, le=1000)

    def net_config(self, n_inputs: int = N_INPUTS, n_outputs: int = N_OUTPUTS) -> RecurrentConfig:
        """The dense net every genome of a search with these settings is run as, for a task of
        `n_inputs` inputs and `n_outputs` outputs (the robot's by default)."""
        return RecurrentConfig(max_hidden=self.max_hidden, n_inputs=n_inputs, n_outputs=n_outputs)
