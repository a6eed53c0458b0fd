"""What the settings' models say about each setting: kind, default, range, unit and description.

The pydantic models (app/settings/config.py, and gnp's `EvolutionConfig`) are the only place a
setting's facts are written. The CLI's options (app/settings/cli_options.py) and the
dashboard's controls (app/dashboard/setting_controls.py) are built from this reading of their
`model_fields`, so a new field of a model shows up in both without another line.
"""

from __future__ import annotations

import math
import types
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from typing import Annotated, Any, Literal, Union, cast, get_args, get_origin

import annotated_types
from pydantic import BaseModel, Field, TypeAdapter, ValidationError
from pydantic.config import JsonDict

Kind = Literal["int", "float", "bool", "choice", "ints"]
"""What a setting holds: a whole number, a real number, a switch, one of some words, or a
list of whole numbers (e.g. sensors)."""

Number = int | float


def about(unit: str | None = None, label: str | None = None) -> JsonDict:
    """Field metadata beyond pydantic's: `Field(..., json_schema_extra=about(unit="mm"))`.

    Args:
        unit: the unit of the value, e.g. "count", "control steps", "s".
        label: a short name for a control or column (default: the field's name in words).
    """
    extra: JsonDict = {}
    if unit is not None:
        extra["unit"] = unit
    if label is not None:
        extra["label"] = label
    return extra


@dataclass(frozen=True)
class Setting:
    """One scalar setting of a model, as its field declares it."""

    path: tuple[str, ...]  # e.g. ("training", "population"); ("seed",) at the top level
    kind: Kind
    default: Any  # None when unset by default, or required
    description: str = ""
    unit: str = ""
    label: str = ""
    choices: tuple[str, ...] = ()
    low: Number | None = None
    high: Number | None = None
    low_open: bool = False  # `gt` rather than `ge`
    high_open: bool = False  # `lt` rather than `le`
    optional: bool = False  # None is allowed ("unset")

    @property
    def name(self) -> str:
        """The field's name."""
        return self.path[-1]

    @property
    def key(self) -> str:
        """The dotted path, as `--set` and error messages name it: `training.population`."""
        return ".".join(self.path)

    def range_text(self) -> str:
        """The allowed values in words: `2..100000`, `> 0, ≤ 1`, `RL|BS|CS`, or ""."""
        if self.choices:
            return "|".join(self.choices)
        if self.low is not None and self.high is not None and not self.low_open | self.high_open:
            return f"{_number(self.low)}..{_number(self.high)}"
        parts = []
        if self.low is not None:
            parts.append(f"{'>' if self.low_open else '≥'} {_number(self.low)}")
        if self.high is not None:
            parts.append(f"{'<' if self.high_open else '≤'} {_number(self.high)}")
        return ", ".join(parts)

    def help(self, default: bool = True) -> str:
        """Description [unit]; range; default — a line for --help or a control's hint."""
        text = self.description + (f" [{self.unit}]" if self.unit else "")
        bounds = self.range_text()
        if bounds and not self.choices:
            text += f"; {bounds}"
        if default and self.default is not None:
            text += f" (default {_shown(self.default)})"
        return text

    def step(self) -> Number:
        """A control's step: 1 for whole numbers; for reals about a thousandth of the range
        (a power of ten), 0.01 when the range is open-ended."""
        if self.kind == "int":
            return 1
        if self.low is None or self.high is None or self.high <= self.low:
            return 0.01
        return float(10 ** round(math.log10((self.high - self.low) / 1000)))


def _number(value: Number) -> str:
    return str(value) if isinstance(value, int) else f"{value:g}"


def _shown(value: Any) -> str:
    """A default as a user would type it: `true`, `0.1`, `2,3`, `none`."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, tuple):
        return ",".join(map(str, value)) or "none"
    return _number(value) if isinstance(value, int | float) else str(value)


def _kind(annotation: Any) -> tuple[Kind, tuple[str, ...]] | None:
    if annotation is bool:
        return "bool", ()
    if annotation is int:
        return "int", ()
    if annotation is float:
        return "float", ()
    if get_origin(annotation) is Literal:
        return "choice", tuple(str(choice) for choice in get_args(annotation))
    if get_origin(annotation) is tuple and get_args(annotation) == (int, Ellipsis):
        return "ints", ()
    return None


def read_setting(model: type[BaseModel], name: str, prefix: tuple[str, ...] = ()) -> Setting | None:
    """The setting `name` of `model` (under `prefix` in a `RunConfig`), or None when it is not
    a scalar (a nested model, an arena)."""
    info = model.model_fields[name]
    annotation, optional = info.annotation, False
    if get_origin(annotation) in (Union, types.UnionType):
        rest = [arg for arg in get_args(annotation) if arg is not type(None)]
        if len(rest) != 1:
            return None
        annotation, optional = rest[0], True
    found = _kind(annotation)
    if found is None:
        return None
    kind, choices = found
    bounds: dict[str, Any] = {}
    for item in info.metadata:
        if isinstance(item, annotated_types.Ge | annotated_types.Gt):
            bounds["low"] = item.ge if isinstance(item, annotated_types.Ge) else item.gt
            bounds["low_open"] = isinstance(item, annotated_types.Gt)
        elif isinstance(item, annotated_types.Le | annotated_types.Lt):
            bounds["high"] = item.le if isinstance(item, annotated_types.Le) else item.lt
            bounds["high_open"] = isinstance(item, annotated_types.Lt)
    extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
    return Setting(
        path=(*prefix, name),
        kind=kind,
        default=None if info.is_required() else info.get_default(call_default_factory=True),
        description=info.description or "",
        unit=str(extra.get("unit", "")),
        label=str(extra.get("label", name.replace("_", " ").capitalize())),
        choices=choices,
        optional=optional,
        **bounds,
    )


def settings_of(model: type[BaseModel], prefix: tuple[str, ...] = ()) -> tuple[Setting, ...]:
    """Every scalar setting of `model`, in the order its fields are declared."""
    found = (read_setting(model, name, prefix) for name in model.model_fields)
    return tuple(s for s in found if s is not None)


def sections(model: type[BaseModel]) -> Iterator[tuple[str, type[BaseModel]]]:
    """The nested models of `model` that are always present: (field name, model class)."""
    for name, info in model.model_fields.items():
        annotation = info.annotation
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            yield name, annotation


class SettingError(ValueError):
    """A value one setting's field refuses; the message is one line, `label: problem (got v)`."""


@cache
def _adapter(model: type[BaseModel], name: str) -> TypeAdapter[Any]:
    info = model.model_fields[name]
    return TypeAdapter(cast(Any, Annotated[info.annotation, info]))


def check_field(model: type[BaseModel], name: str, value: Any, label: str) -> Any:
    """`value` checked against the field `name` of `model` alone (its type and bounds; not the
    model's checks across fields), as the field makes it (e.g. 3 → 3.0 for a float).

    Raises:
        SettingError: `label: problem (got value)`.
    """
    try:
        return _adapter(model, name).validate_python(value)
    except ValidationError as error:
        problem = str(error.errors()[0]["msg"])
        raise SettingError(f"{label}: {problem} (got {value!r})") from None


def value_at(model: BaseModel, path: tuple[str, ...]) -> Any:
    """The value of the setting at `path` in `model` (e.g. a `RunConfig`)."""
    value: Any = model
    for part in path:
        value = getattr(value, part)
    return value


def nested(values: dict[tuple[str, ...], Any]) -> dict[str, Any]:
    """{("training", "steps"): 60} → {"training": {"steps": 60}}, a layer for `build_config`."""
    layer: dict[str, Any] = {}
    for path, value in values.items():
        target = layer
        for part in path[:-1]:
            target = target.setdefault(part, {})
        target[path[-1]] = value
    return layer


def setting(
    default: Any,
    description: str,
    unit: str | None = None,
    *,
    label: str | None = None,
    **constraints: Any,
) -> Any:
    """A model field with its facts: `setting(300, "individuals", "count", ge=2, le=100_000)`.

    Args:
        default: the value when the setting is not given.
        description: what the setting is, in a few words (help text and hints).
        unit: its unit (see `about`).
        label: a short name for controls (see `about`).
        **constraints: pydantic's `Field` bounds (`ge`, `gt`, `le`, `lt`, `max_length`).
    """
    return Field(
        default, description=description, json_schema_extra=about(unit, label), **constraints
    )
