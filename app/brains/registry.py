"""The registry of brain families: `register(Family)` and `family_of(config)`.

As Gymnasium's `register(id, entry_point)` and `make`: a family is registered under its class's
`name`, by its class, or under a name by a `"module:Class"` string imported on first use (so a
run of GNP never imports pycma or neat-python), checked against the class's `name` then. The
table itself is the settings' (`app.settings.families`), so that a config's `brain` section is
checked with its family's model wherever it is read. A family defined outside the lab registers
itself when its module is imported; list such modules in the environment variable
`GNP_LAB_BRAINS` (comma-separated), and every process of the lab (the CLI, its worker processes,
Dask workers, which inherit the environment) imports them before it looks a family up.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from app.settings import families
from app.settings.config import ConfigError, RunConfig
from app.settings.families import BUILT_IN, DEFAULT_BRAIN, PLUGINS_VARIABLE
from app.store import RunSummary
from app.store.controller_file import Controller, ControllerFormat, read_controller

if TYPE_CHECKING:
    from app.brains.contract import BrainFamily, BrainIO

__all__ = [
    "BUILT_IN",
    "PLUGINS_VARIABLE",
    "controller_formats",
    "family_class",
    "family_of",
    "load_controller",
    "names",
    "register",
    "register_controller_format",
]


def register(
    family: type[BrainFamily] | str,
    entry_point: str | None = None,
    settings: str | None = None,
) -> None:
    """Register a family: its class, under its `name` (`register(Vehicle)`); or under the name
    `family` a `"module:Class"` `entry_point` imported on first use, with its settings model
    `settings` (`"module:Class"`, default the class's `settings_model`), their names checked
    then. Registering a name again replaces it (a module imported twice registers twice).

    Raises:
        ValueError: not a valid name.
        ConfigError: a class whose names disagree (`app.settings.families.disagreements`).
    """
    entry: type[BrainFamily] | str
    if isinstance(family, str):
        name, entry = family, entry_point or ""
        if not entry:
            raise ValueError(f'register({name!r}) needs the family\'s "module:Class"')
    else:
        name, entry = family.name, family
        families.refuse(name, families.disagreements(name, family))
    if not name or not name.replace("-", "").replace("_", "").isalnum():
        raise ValueError(f"a brain family's name is letters, digits, '-' and '_', got {name!r}")
    families.enter(name, entry, settings)


def names() -> tuple[str, ...]:
    """Every registered family's name: the lab's own first."""
    return families.names()


def family_class(name: str) -> type[BrainFamily]:
    """The class registered under `name`.

    Raises:
        ConfigError: no family of that name (the known ones are listed).
    """
    found: type[BrainFamily] = families.family_class(name)
    return found


def family_of(config: RunConfig, io: BrainIO | None = None) -> BrainFamily:
    """The family of `config` (`config.brain.family`), bound to it, its brains reading and
    emitting `io` (`app.brains.contract.BrainIO`; the robot's when None: a family written
    before `io` existed is bound as it was).

    Raises:
        ConfigError: an unknown family, settings its family refuses, or an `io` it cannot
            take (one line).
    """
    cls = family_class(config.brain.family)
    return cls(config) if io is None else cls(config, io)


def run_kind(summary: RunSummary) -> str:
    """A run list's words for a run: its family's description (`CS fuzzy`, `cmaes: Elman net,
    8 hidden`), `task CartPole-v1` of a task run (`task CartPole-v1 (cmaes)` of a family other
    than the default, GNP), or the name of a family not registered here."""
    if summary.task:
        family = summary.task_family
        return f"task {summary.task}" + (f" ({family})" if family != DEFAULT_BRAIN else "")
    if summary.config is None:  # unreadable: the list says so itself
        return ""
    try:
        return family_of(summary.config).description
    except ConfigError:
        return f"{summary.config.brain.family} (not registered)"


_formats: dict[str, ControllerFormat | str] = {
    "gnp-lab-controller": "app.brains.gnp_file:GNP_FILE",
    "gnp-lab-neural-controller": "app.brains.net_file:NET_FILE",
}


def register_controller_format(form: ControllerFormat) -> None:
    """Register a family's controller file format under its name (a document's `format`)."""
    _formats[form.name] = form


def controller_formats() -> dict[str, ControllerFormat]:
    """Every registered controller file format, by name: the lab's own first."""
    families.load_plugins()
    for name, entry in _formats.items():
        if isinstance(entry, str):
            _formats[name] = families.resolved(entry)
    return {name: form for name, form in _formats.items() if not isinstance(form, str)}


def load_controller(path: str | Path) -> Controller:
    """Read a controller file of any registered family, checked (a `GnpController`, a
    `NetController`, …; see `app.store.controller_file.read_controller`).

    Raises:
        app.store.controller_file.ControllerFileError: the file is not a controller of a
            registered format, or an invalid one (one line naming the problem).
    """
    return read_controller(path, controller_formats())
