"""Controller files: one trained controller as a JSON document, its envelope written and read.

A document is an envelope, written and read here for every brain family, around a body its
family writes and reads (`app.brains`: GNP's `app.brains.gnp_file`, the nets'
`app.brains.net_file`, found by the document's format in `app.brains.registry`):

    {"format": "gnp-lab-controller", "version": 1, "gnp": {...}, "settings": {...}, "nodes": [...]}
    {"format": "gnp-lab-neural-controller", "version": 1, "net": {...}, "settings": {...},
     "arrays": {...}}

The schema is in docs/controller-format.md. `settings` says what the lab ran the controller with
(free form). Floats are written as Python's shortest round-trip repr, so a loaded controller
steps bit-identically to the saved one.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from app.settings.user_files import loads_json, read_text


class ControllerFileError(ValueError):
    """A controller file that cannot be written or read (the message names the problem)."""


class Controller(Protocol):
    """One trained controller of some family, with what the lab ran it with."""

    @property
    def settings(self) -> dict[str, Any]: ...

    def document(self) -> dict[str, Any]:
        """The controller as its JSON document (its format's envelope around its body).

        Raises:
            ControllerFileError: it is not one controller (named).
        """
        ...


@dataclass(frozen=True)
class ControllerFormat:
    """One family's envelope: its format name and version, the keys of its config and body,
    and how the family reads them back (`read(config, body, settings)`, raising
    `ControllerFileError` or any structural error of the JSON when they are not a controller)."""

    name: str
    version: int
    config_key: str
    body_key: str
    read: Callable[[Any, Any, dict[str, Any]], Controller]

    def document(self, config: Any, settings: dict[str, Any], body: Any) -> dict[str, Any]:
        """The envelope around a family's config and body."""
        return {
            "format": self.name,
            "version": self.version,
            self.config_key: config,
            "settings": settings,
            self.body_key: body,
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
    return save_document(path, controller.document())


def read_controller(path: str | Path, formats: Mapping[str, ControllerFormat]) -> Controller:
    """Read a controller file of one of `formats` (by name), checked.

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
    form = formats.get(name) if isinstance(name, str) else None
    if form is None:
        raise ControllerFileError(
            f"{path} is not a gnp-lab controller (no format {' or '.join(map(repr, formats))})"
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
        return form.read(document[form.config_key], document[form.body_key], settings)
    except ControllerFileError as error:
        raise ControllerFileError(f"{path}: {error}") from None
    # Any structural error of the JSON (a list where a mapping belongs, a row too short...)
    # ends in one line, whichever lookup met it first.
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as error:
        first_line = str(error).splitlines()[0] if str(error) else ""
        raise ControllerFileError(
            f"{path}: malformed controller ({type(error).__name__}: {first_line})"
        ) from None
