"""The nets' settings: the `brain` section of a CMA-ES or NEAT run (issue #23).

Light (pydantic, neuro's NEAT parameters, app.settings): checked wherever a config is read,
without pycma or neat-python.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from app.settings.families import BrainSettings
from app.settings.fields import setting
from neuro.neat_params import NeatParams


class NetSettings(BrainSettings):
    """A neural controller instead of GNP: an Elman net evolved by CMA-ES (pycma), or a NEAT net
    (neat-python). It does not learn online; training's ε/α are unused."""

    family: Literal["cmaes", "neat"] = Field(
        description="CMA-ES on an Elman net's weights, or NEAT"
    )
    hidden: int = setting(8, "Elman hidden units (CMA-ES)", "count", ge=1, le=64)
    sigma0: float = setting(0.5, "CMA-ES initial step size, from weights 0", "1", gt=0.0, le=10.0)
    neat: NeatParams = NeatParams()
