"""The registry of brain families: `register(name, entry_point)` and `family_of(config)`; and of
their controller files' formats (`register_controller_format`, `load_controller`).

As Gymnasium's `register(id, entry_point)` and `make`: a family is registered under its name,
by its class or by a `"module:Class"` string imported on first use (so a run of GNP never imports
pycma or neat-python). A family defined outside the lab registers itself when its module is
imported; list such modules in the environment variable `GNP_LAB_BRAINS` (comma-separated), and
every process of the lab (the CLI, its worker processes, Dask workers, which inherit the
environment) imports them before it looks a family up.
"""

from __future__ import annotations

import importlib
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.settings.config import DEFAULT_BRAIN, ConfigError, RunConfig
from app.store import RunSummary
from app.store.controller_file import Controller, ControllerFormat, read_controller

if TYPE_CHECKING:
    from app.brains.contract import BrainFamily

PLUGINS_VARIABLE = "GNP_LAB_BRAINS"
"""Modules that register brain families, imported before a family is looked up."""

_registry: dict[str, type[BrainFamily] | str] = {
    DEFAULT_BRAIN: "app.brains.gnp_brain:GnpFamily",
    "cmaes": "app.brains.nets:CmaesFamily",
    "neat": "app.brains.nets:NeatFamily",
}
BUILT_IN = tuple(_registry)
"""The lab's own families, in the order the CLI and the dashboard offer them."""
_plugins_loaded: set[str] = set()


def register(name: str, entry_point: type[BrainFamily] | str) -> None:
    """Register a family under `name`: its class, or `"module:Class"` imported on first use.
    Registering a name again replaces it (a module imported twice registers twice)."""
    if not name or not name.replace("-", "").replace("_", "").isalnum():
        raise ValueError(f"a brain family's name is letters, digits, '-' and '_', got {name!r}")
    _registry[name] = entry_point


def _load_plugins() -> None:
    for module in os.environ.get(PLUGINS_VARIABLE, "").split(","):
        module = module.strip()
        if module and module not in _plugins_loaded:
            _plugins_loaded.add(module)
            try:
                importlib.import_module(module)
            except ImportError as error:
                raise ConfigError(
                    f"{PLUGINS_VARIABLE} names {module!r}, which cannot be imported: {error}"
                ) from None


def names() -> tuple[str, ...]:
    """Every registered family's name: the lab's own first."""
    _load_plugins()
    return tuple(_registry)


def family_class(name: str) -> type[BrainFamily]:
    """The class registered under `name`.

    Raises:
        ConfigError: no family of that name (the known ones are listed).
    """
    _load_plugins()
    entry = _registry.get(name)
    if entry is None:
        raise ConfigError(
            f"unknown brain family {name!r}; known: {', '.join(_registry)} "
            f"(a family of your own: register it in a module named in {PLUGINS_VARIABLE})"
        )
    if isinstance(entry, str):
        entry = _resolved(entry)
        assert not isinstance(entry, str)
        _registry[name] = entry
    return entry


def family_of(config: RunConfig) -> BrainFamily:
    """The family of `config` (`config.brain`), bound to it.

    Raises:
        ConfigError: an unknown family, or settings its family refuses.
    """
    return family_class(config.brain)(config)


def run_kind(summary: RunSummary) -> str:
    """A run list's words for a run: its family's description (`CS fuzzy`, `cmaes: Elman net,
    8 hidden`), `task CartPole-v1` of a task run, or the name of a family not registered here."""
    if summary.task:
        return f"task {summary.task}"
    if summary.config is None:  # unreadable: the list says so itself
        return ""
    try:
        return family_of(summary.config).description
    except ConfigError:
        return f"{summary.config.brain} (not registered)"


_formats: dict[str, ControllerFormat | str] = {
    "gnp-lab-controller": "app.brains.gnp_file:GNP_FILE",
    "gnp-lab-neural-controller": "app.brains.net_file:NET_FILE",
}


def register_controller_format(form: ControllerFormat) -> None:
    """Register a family's controller file format under its name (a document's `format`)."""
    _formats[form.name] = form


def controller_formats() -> dict[str, ControllerFormat]:
    """Every registered controller file format, by name: the lab's own first."""
    _load_plugins()
    for name, entry in _formats.items():
        if isinstance(entry, str):
            _formats[name] = _resolved(entry)
    return {name: form for name, form in _formats.items() if not isinstance(form, str)}


def _resolved(entry: str) -> Any:
    """What a `"module:attribute"` entry names, its module imported."""
    module, _, attribute = entry.partition(":")
    return getattr(importlib.import_module(module), attribute)


def load_controller(path: str | Path) -> Controller:
    """Read a controller file of any registered family, checked (a `GnpController`, a
    `NetController`, …; see `app.store.controller_file.read_controller`).

    Raises:
        app.store.controller_file.ControllerFileError: the file is not a controller of a
            registered format, or an invalid one (one line naming the problem).
    """
    return read_controller(path, controller_formats())
