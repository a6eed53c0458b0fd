"""The table of brain families: each name's family class and settings model, as entry points.

A run's config names its family in `brain.family`; its `brain` section is checked with the
model the family declares (a subclass of `BrainSettings`). The models live with their families
(app/brains), above this layer: the table holds them as `"module:Class"` strings, imported on
first use (Gymnasium's `register(id, entry_point)`), so the settings never import a family.
`app.brains.register` writes here.

A family's name is written once, as its class's `name`: a class is filed under it, and a
`"module:Class"` entry's key is checked against it when the class is imported; the settings
model's `family` default (if it has one) must be it too (`disagreements`).

Families defined outside the lab register themselves when their module is imported: list such
modules in `GNP_LAB_BRAINS` (comma-separated), and every process of the lab (the CLI, its worker
processes, Dask workers, which inherit the environment) imports them before it looks a family
up.
"""

from __future__ import annotations

import importlib
import os
from dataclasses import dataclass
from typing import Any, Literal, get_args, get_origin

from pydantic import BaseModel, ConfigDict, Field

from app.settings.errors import ConfigError

DEFAULT_BRAIN = "gnp"
"""The brain family of a config that names none: GNP, the thesis's."""

PLUGINS_VARIABLE = "GNP_LAB_BRAINS"
"""Modules that register brain families, imported before a family is looked up."""


class BrainSettings(BaseModel):
    """A run's `brain` section: the family that runs, and (in the family's subclass) its own
    settings. A family declares its subclass as `settings_model` (app/brains/contract.py)."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    family: str = Field(default=DEFAULT_BRAIN, description="the brain family's registered name")


class UnregisteredBrain(BrainSettings):
    """The `brain` section of a family not registered here: kept as it is (a run list names
    it); binding it to a family (`app.brains.family_of`) is refused."""

    model_config = ConfigDict(frozen=True, extra="allow")


@dataclass
class Entry:
    """One registered family: its class and its settings model, each a class or "module:Class"
    (None: the family class's `settings_model`)."""

    family: Any
    settings: type[BrainSettings] | str | None = None


_table: dict[str, Entry] = {
    DEFAULT_BRAIN: Entry("app.brains.gnp_brain:GnpFamily", "app.brains.gnp_settings:GnpSettings"),
    "cmaes": Entry("app.brains.nets:CmaesFamily", "app.brains.net_settings:NetSettings"),
    "neat": Entry("app.brains.nets:NeatFamily", "app.brains.net_settings:NetSettings"),
}
BUILT_IN = tuple(_table)
"""The lab's own families, in the order the CLI and the dashboard offer them."""
_plugins_loaded: set[str] = set()


def enter(name: str, family: Any, settings: type[BrainSettings] | str | None = None) -> None:
    """Put `name` in the table (again: replaced). `app.brains.register` checks the name."""
    _table[name] = Entry(family, settings)


def load_plugins() -> None:
    """Import the modules `GNP_LAB_BRAINS` names (each once it imports).

    Raises:
        ConfigError: a module cannot be imported.
    """
    for module in os.environ.get(PLUGINS_VARIABLE, "").split(","):
        module = module.strip()
        if module and module not in _plugins_loaded:
            try:
                importlib.import_module(module)
            except ImportError as error:
                raise ConfigError(
                    f"{PLUGINS_VARIABLE} names {module!r}, which cannot be imported: {error}"
                ) from None
            _plugins_loaded.add(module)


def names() -> tuple[str, ...]:
    """Every registered family's name: the lab's own first."""
    load_plugins()
    return tuple(_table)


def resolved(entry: Any) -> Any:
    """What a `"module:attribute"` entry names (its module imported), or the entry itself."""
    if isinstance(entry, str):
        module, _, attribute = entry.partition(":")
        return getattr(importlib.import_module(module), attribute)
    return entry


def entry(name: str) -> Entry:
    """The table's entry of `name`.

    Raises:
        ConfigError: no family of that name (the known ones are listed).
    """
    load_plugins()
    found = _table.get(name)
    if found is None:
        raise ConfigError(
            f"unknown brain family {name!r}; known: {', '.join(_table)} "
            f"(a family of your own: register it in a module named in {PLUGINS_VARIABLE})"
        )
    return found


def disagreements(name: str, family: Any, settings: Any = None) -> list[str]:
    """Where a family's names disagree: its table key `name`, its class's `name` and its
    settings model's `family` (the table's model, else the class's `settings_model`)."""
    problems = []
    declared = getattr(family, "name", None)
    if declared != name:
        problems.append(f"{family.__module__}.{family.__qualname__}.name is {declared!r}")
    declared_model = getattr(family, "settings_model", None)
    model = settings if settings is not None else declared_model
    if settings is not None and declared_model is not None and settings is not declared_model:
        problems.append(f"its settings model is {settings.__name__}, not its class's")
    if isinstance(model, type) and issubclass(model, BrainSettings):
        problems += model_disagreements(name, model)
    return problems


def model_disagreements(name: str, model: type[BrainSettings]) -> list[str]:
    """Where settings model `model` disagrees with family name `name`: its `family` default
    (the base `BrainSettings`' is the config's default family, not a family's own) or choices."""
    field = model.model_fields["family"]
    if model is not BrainSettings and not field.is_required() and field.default != name:
        return [f"{model.__name__}.family defaults to {field.default!r}"]
    choices = get_args(field.annotation) if get_origin(field.annotation) is Literal else ()
    if choices and name not in choices:
        return [f"{model.__name__}.family admits only {', '.join(map(repr, choices))}"]
    return []


def refuse(name: str, problems: list[str]) -> None:
    """Raise if family `name` has `problems` (of `disagreements`).

    Raises:
        ConfigError: one line naming each disagreement.
    """
    if problems:
        raise ConfigError(f"brain family {name!r} is named otherwise: {'; '.join(problems)}")


def family_class(name: str) -> Any:
    """The class registered under `name`, imported on first use (see `entry`) and its names
    checked (see `disagreements`)."""
    found = entry(name)
    if isinstance(found.family, str):
        family = resolved(found.family)
        refuse(name, disagreements(name, family, resolved(found.settings)))
        found.family = family
    return found.family


def settings_model(name: str) -> type[BrainSettings] | None:
    """The settings model of family `name`; None for a family not registered here.

    Raises:
        ConfigError: a plug-in module cannot be imported (see `load_plugins`).
    """
    load_plugins()
    found = _table.get(name)
    if found is None:
        return None
    if found.settings is None:
        declared = getattr(family_class(name), "settings_model", None)
        found.settings = declared or BrainSettings
    if isinstance(found.settings, str):
        model = resolved(found.settings)
        assert isinstance(model, type) and issubclass(model, BrainSettings)
        refuse(name, model_disagreements(name, model))
        found.settings = model
    assert isinstance(found.settings, type) and issubclass(found.settings, BrainSettings)
    return found.settings


def brain_section(value: Any) -> Any:
    """A `brain` section checked with its family's model (an unregistered family's kept
    loose); what is not a table is left for the field's own check."""
    if isinstance(value, BrainSettings):
        if type(value) is (settings_model(value.family) or UnregisteredBrain):
            return value
        value = value.model_dump()
    if not isinstance(value, dict):
        return value
    name = value.get("family", DEFAULT_BRAIN)
    model = settings_model(name) if isinstance(name, str) else BrainSettings
    return (model or UnregisteredBrain).model_validate(value)
