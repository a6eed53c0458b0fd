"""GNP's controller files: one individual (Q tables included), its body written by `gnp`.

The envelope is `app.store.controller_file`'s; the body is `gnp.controller_body`'s (the config
under "gnp", the nodes under "nodes"; docs/controller-format.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import gnp
from app.store.controller_file import ControllerFileError, ControllerFormat


@dataclass(frozen=True)
class GnpController:
    """One GNP individual (a 1-individual population, Q tables included) and its settings."""

    cfg: gnp.GnpConfig
    individual: gnp.Population
    settings: dict[str, Any] = field(default_factory=dict)

    def document(self) -> dict[str, Any]:
        try:
            config, body = gnp.controller_body(self.cfg, self.individual)
        except gnp.GnpError as error:
            raise ControllerFileError(str(error)) from None
        return GNP_FILE.document(config, self.settings, body)


def _read(config: Any, body: Any, settings: dict[str, Any]) -> GnpController:
    try:
        return GnpController(*gnp.controller_from_body(config, body), settings)
    except gnp.GnpError as error:
        raise ControllerFileError(str(error)) from None


GNP_FILE = ControllerFormat("gnp-lab-controller", 1, "gnp", "nodes", _read)
"""The envelope of a GNP controller."""
