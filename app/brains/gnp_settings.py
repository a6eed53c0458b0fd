"""GNP's settings: the `brain` section of a GNP run (`controller`, `evolution`).

Light (pydantic, gnp's config, app.settings): a config is checked with `GnpSettings` wherever
it is read, run lists included, without the family's kernels.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.settings.config import METHOD_PRESET, RunConfig, preset_layer
from app.settings.families import BrainSettings
from app.settings.fields import read_setting, setting
from gnp import METHODS, TRAITS, EvolutionConfig, GnpConfig, Method
from gnp.config import (
    ProcessingOutput,
    SkipReward,
    ThresholdInit,
    TieBreak,
    check_judgment_branches,
)


def _of_gnp(name: str, unit: str | None = None, **narrower: Any) -> Any:
    """A `ControllerSettings` field with the default and description `gnp.GnpConfig` gives it
    (written there once), and its bounds unless the lab allows `narrower` ones."""
    fact = read_setting(GnpConfig, name)
    assert fact is not None, name
    bounds = dict(narrower)
    if not narrower and fact.low is not None:
        bounds["gt" if fact.low_open else "ge"] = fact.low
    if not narrower and fact.high is not None:
        bounds["lt" if fact.high_open else "le"] = fact.high
    return setting(fact.default, fact.description, unit, **bounds)


class ControllerSettings(BaseModel):
    """The GNP individual (Tables 2.4, 3.1, 5.1). Defaults and descriptions are gnp's
    (`GnpConfig`); the lab keeps narrower bounds on the sizes."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    method: Method = Field(
        default=preset_layer(METHOD_PRESET)["brain"]["controller"]["method"],
        description="GNP-RL (RL), GNP-TSRL with branch selection (BS) or credit (CS)",
    )
    fuzzy: bool = _of_gnp("fuzzy")
    n_judgment: int = _of_gnp("n_judgment", "count", ge=8, le=400)
    n_processing: int = _of_gnp("n_processing", "count", ge=2, le=200)
    n_sub: int | None = setting(
        None,
        "sub nodes per node; unset = the thesis's choice for the method ("
        + ", ".join(f"{m} {TRAITS[m].default_n_sub}" for m in METHODS)
        + "; Tables 3.1, 5.1)",
        "count",
        ge=1,
        le=8,
    )
    n_branch: int = _of_gnp("n_branch", ge=1, le=8)
    gamma: float = _of_gnp("gamma", "1")
    q0: float = _of_gnp("q0", "1")
    tie_break: TieBreak = _of_gnp("tie_break")
    skip_reward: SkipReward = _of_gnp("skip_reward")
    threshold_init: ThresholdInit = _of_gnp("threshold_init")
    processing_output: ProcessingOutput = _of_gnp("processing_output")
    judgment_branches: int = _of_gnp("judgment_branches", "count")

    @model_validator(mode="after")
    def _branches_judged(self) -> ControllerSettings:
        check_judgment_branches(self.fuzzy, self.judgment_branches)
        return self

    @property
    def sub_nodes(self) -> int:
        """Sub nodes per node, resolving the method's thesis default."""
        if self.n_sub is not None:
            return self.n_sub
        return TRAITS[self.method].default_n_sub

    def gnp_config(self) -> GnpConfig:
        """The brain's config for these settings."""
        return GnpConfig(
            method=self.method,
            fuzzy=self.fuzzy,
            n_judgment=self.n_judgment,
            n_processing=self.n_processing,
            n_sub=self.sub_nodes,
            n_branch=self.n_branch,
            gamma=self.gamma,
            q0=self.q0,
            tie_break=self.tie_break,
            skip_reward=self.skip_reward,
            threshold_init=self.threshold_init,
            processing_output=self.processing_output,
            judgment_branches=self.judgment_branches,
        )


class GnpSettings(BrainSettings):
    """A GNP run's `brain` section: the individual and its evolution."""

    controller: ControllerSettings = ControllerSettings()
    evolution: EvolutionConfig = EvolutionConfig()


def gnp_settings(config: RunConfig) -> GnpSettings:
    """The GNP settings of `config`, a GNP run's.

    Raises:
        ValueError: `config` runs another family.
    """
    if not isinstance(config.brain, GnpSettings):
        raise ValueError(f"a GNP run's config is needed, not one of {config.brain.family!r}")
    return config.brain
