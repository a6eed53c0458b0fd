"""Neural nets' controller files: one net and its weights, its body written by `neuro`.

The envelope is `app.store.controller_file`'s; the body is `neuro.net_body`'s (the net's shape
under "net", its arrays under "arrays"; docs/controller-format.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

import neuro
from app.store.controller_file import ControllerFileError, ControllerFormat


@dataclass(frozen=True)
class NetController:
    """One neural net (arrays with a leading axis of 1) and its settings."""

    net: neuro.NetConfig
    arrays: dict[str, np.ndarray]
    settings: dict[str, Any] = field(default_factory=dict)

    def document(self) -> dict[str, Any]:
        try:
            config, body = neuro.net_body(self.net, self.arrays)
        except neuro.NeuroError as error:
            raise ControllerFileError(str(error)) from None
        return NET_FILE.document(config, self.settings, body)


def _read(config: Any, body: Any, settings: dict[str, Any]) -> NetController:
    try:
        return NetController(*neuro.net_from_body(config, body), settings)
    except neuro.NeuroError as error:
        raise ControllerFileError(str(error)) from None


NET_FILE = ControllerFormat("gnp-lab-neural-controller", 1, "net", "arrays", _read)
"""The envelope of a neural controller (CMA-ES's Elman net, NEAT's genome)."""
