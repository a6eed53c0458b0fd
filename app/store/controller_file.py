"""Controller files: one trained GNP individual or neural net as a JSON document, read and written.

A document is an envelope, written and read here for both brain families, around a body that
`gnp` or `neuro` converts (they import neither each other nor `app`):

    {"format": "gnp-lab-controller", "version": 1, "gnp": {...}, "settings": {...}, "nodes": [...]}
    {"format": "gnp-lab-neural-controller", "version": 1, "net": {...}, "settings": {...},
     "arrays": {...}}

The schema is in docs/controller-format.md. `settings` says what the lab ran the controller with
(free form). Floats are written as Python's shortest round-trip repr, so `load_controller` gives
back a controller that steps bit-identically to the saved one.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import gnp
import neuro
from app.settings.user_files import loads_json, read_text


class ControllerFileError(ValueError):
    """A controller file that cannot be written or read (the message names the problem)."""


@dataclass(frozen=True)
class GnpController:
    """One GNP individual (a 1-individual population, Q tables included) and its settings."""

    cfg: gnp.GnpConfig
    individual: gnp.Population
    settings: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class NetController:
    """One neural net (arrays with a leading axis of 1) and its settings."""

    net: neuro.NetConfig
    arrays: dict[str, np.ndarray]
    settings: dict[str, Any] = field(default_factory=dict)


Controller = GnpController | NetController


@dataclass(frozen=True)
class _Format:
    """One family's envelope: its format name and version, the keys of its config and body."""

    name: str
    version: int
    config_key: str
    body_key: str


_GNP = _Format("gnp-lab-controller", 1, "gnp", "nodes")
_NET = _Format("gnp-lab-neural-controller", 1, "net", "arrays")
FORMATS = {form.name: form for form in (_GNP, _NET)}


def controller_document(controller: Controller) -> dict[str, Any]:
    """`controller` as its JSON document (the envelope around its family's body).

    Raises:
        ControllerFileError: the controller is not one individual or net (named).
    """
    config: dict[str, Any]
    body: Any
    try:
        if isinstance(controller, GnpController):
            form, (config, body) = _GNP, gnp.controller_body(controller.cfg, controller.individual)
        else:
            form, (config, body) = _NET, neuro.net_body(controller.net, controller.arrays)
    except (gnp.GnpError, neuro.NeuroError) as error:
        raise ControllerFileError(str(error)) from None
    return {
        "format": form.name,
        "version": form.version,
        form.config_key: config,
        "settings": controller.settings,
        form.body_key: body,
    }


def save_document(path: str | Path, document: dict[str, Any]) -> Path:
    """Write a controller document as `path` (JSON, one line a value)."""
    path = Path(path)
    path.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    return path


def save_controller(path: str | Path, controller: Controller) -> Path:
    """Write `controller` as `path` (JSON, one line a value).

    Raises:
        ControllerFileError: the controller is not one individual or net (named).
    """
    return save_document(path, controller_document(controller))


def load_controller(path: str | Path) -> Controller:
    """Read a controller file of either family, checked: a `GnpController` or a `NetController`.

    Raises:
        ControllerFileError: the file is missing, not a regular file, too large or deep (see
            `app.settings.user_files`), not JSON, not a controller of a known format
            and version, or holds an invalid genome or net (the message names the problem).
    """
    path = Path(path)
    what = "controller file"
    text = read_text(path, ControllerFileError, what)
    document = loads_json(text, ControllerFileError, f"{what} {path}")
    name = document.get("format") if isinstance(document, dict) else None
    form = FORMATS.get(name) if isinstance(name, str) else None
    if form is None:
        raise ControllerFileError(
            f"{path} is not a gnp-lab controller (no format {' or '.join(map(repr, FORMATS))})"
        )
    if document.get("version") != form.version:
        raise ControllerFileError(
            f"{path} is {form.name} version {document.get('version')!r}; "
            f"this gnp-lab reads version {form.version}"
        )
    settings = document.get("settings", {})
    if not isinstance(settings, dict):
        raise ControllerFileError(f"{path}: settings must be a JSON object")
    try:
        config, body = document[form.config_key], document[form.body_key]
        if form is _GNP:
            return GnpController(*gnp.controller_from_body(config, body), settings)
        return NetController(*neuro.net_from_body(config, body), settings)
    except (gnp.GnpError, neuro.NeuroError) as error:
        raise ControllerFileError(f"{path}: {error}") from None
    # Any structural error of the JSON (a list where a mapping belongs, a row too short...)
    # ends in one line, whichever lookup met it first.
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as error:
        first_line = str(error).splitlines()[0] if str(error) else ""
        raise ControllerFileError(
            f"{path}: malformed controller ({type(error).__name__}: {first_line})"
        ) from None
