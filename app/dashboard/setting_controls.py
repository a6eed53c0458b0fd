"""Viser controls built from the settings' models: bounds, step, default and hint come from the
field (`app.settings.fields.Setting`), so no range is typed again for the page. What a control
holds is checked by building the model, never by a check of its own."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import cache
from types import MappingProxyType
from typing import Any

import viser
from pydantic import BaseModel

from app.dashboard.controls import DashboardInputError
from app.dashboard.status import set_value
from app.settings.config import ImplementationSettings
from app.settings.fields import Setting, SettingError, check_field, settings_of, value_at

Control = viser.GuiNumberHandle[Any] | viser.GuiDropdownHandle[Any] | viser.GuiCheckboxHandle


@cache
def implementation_settings() -> Mapping[str, Setting]:
    """The implementation phase's settings by field name (`ImplementationSettings`), read once
    for the Runs, Compare and Faults tabs."""
    return MappingProxyType({s.name: s for s in settings_of(ImplementationSettings)})


def add_number(
    gui: viser.GuiApi, setting: Setting, value: float, label: str = ""
) -> viser.GuiNumberHandle[Any]:
    """A number input with the field's bounds, a step to suit them, and the field's
    description, unit, range and default as its hint."""
    return gui.add_number(
        label or setting.label,
        value,
        min=setting.low,
        max=setting.high,
        step=setting.step(),
        hint=setting.help(),
    )


def add_choice(
    gui: viser.GuiApi, setting: Setting, value: str, label: str = ""
) -> viser.GuiDropdownHandle[str]:
    """A dropdown of the field's choices, with its description and default as its hint."""
    return gui.add_dropdown(
        label or setting.label, setting.choices, initial_value=value, hint=setting.help()
    )


def add_control(gui: viser.GuiApi, setting: Setting, value: Any, label: str = "") -> Control:
    """A control for `setting` holding `value`: a checkbox, a dropdown or a number input."""
    if setting.kind == "bool":
        hint = setting.help()
        return gui.add_checkbox(label or setting.label, initial_value=bool(value), hint=hint)
    if setting.kind == "choice":
        return add_choice(gui, setting, str(value), label)
    if setting.kind in ("int", "float"):
        return add_number(gui, setting, value, label)
    raise ValueError(f"no control for {setting.key} ({setting.kind})")


def can_show(setting: Setting) -> bool:
    """Whether a control can hold the setting (not a list, and never unset)."""
    return setting.kind != "ints" and not setting.optional


@dataclass
class SettingControls:
    """Controls of some settings of one model, by path."""

    controls: dict[tuple[str, ...], Control]

    def values(self) -> dict[tuple[str, ...], Any]:
        """{path: value} as the controls hold them now."""
        return {path: control.value for path, control in self.controls.items()}

    def show(self, model: BaseModel) -> None:
        """Put each setting's value in `model` into its control."""
        for path, control in self.controls.items():
            set_value(control, value_at(model, path))


def add_controls(
    gui: viser.GuiApi, settings: Iterable[Setting], model: BaseModel
) -> SettingControls:
    """A control per setting, holding its value in `model`."""
    return SettingControls(
        {s.path: add_control(gui, s, value_at(model, s.path)) for s in settings if can_show(s)}
    )


def check(model: type[BaseModel], name: str, value: Any, label: str) -> Any:
    """`value` checked against the field `name` of `model` alone (its type and bounds).

    Raises:
        DashboardInputError: `label: problem (got value)`.
    """
    try:
        return check_field(model, name, value, label)
    except SettingError as error:
        raise DashboardInputError(str(error)) from None
