"""Run configurations in and out: layered from defaults, presets, TOML files and options;
written as TOML; read back from a run file's stored JSON; and the settings the CLI offers.

Every problem is a `ConfigError` on one line naming the field, what it allows and the value.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import (
    BaseModel,
    ValidationError,
)

from app.settings.arenas import read_arena_paths, toml_arena
from app.settings.config import (
    ConfigError,
    ImplementationSettings,
    RunConfig,
    preset_layer,
)
from app.settings.families import DEFAULT_BRAIN, settings_model
from app.settings.fields import Setting, sections, settings_of
from app.settings.layouts import deep_merge, layout_2
from app.settings.user_files import loads_json, loads_toml, read_text


def describe_problems(error: ValidationError, limit: int | None = None) -> str:
    """A pydantic error as one line: `field: problem (got value)`, joined by "; ", the first
    `limit` of them and a count of the rest."""
    problems = []
    items = error.errors()
    for item in items[:limit]:
        field = ".".join(str(part) for part in item["loc"])
        message = str(item["msg"]).removeprefix("Value error, ")
        if item["type"] == "extra_forbidden":
            message = "unknown setting"
        given = item.get("input")
        shown = not isinstance(given, Mapping | list | tuple) and given is not None
        where = f"{field}: " if field else ""  # a model's own check names its fields
        problems.append(f"{where}{message}" + (f" (got {given!r})" if shown else ""))
    more = len(items) - len(problems)
    return ("; ".join(problems) + (f" (and {more} more)" if more else "")).replace("\n", " ")


def _format_errors(error: ValidationError, source: str) -> str:
    return f"invalid configuration in {source}: " + describe_problems(error)


def _check_tables(layer: Mapping[str, Any], source: str) -> None:
    """Refuse a section of the config (e.g. `training`) given a value that is not a table:
    merged with another layer's table it would otherwise be dropped without a word.

    Raises:
        ConfigError: naming the section and the value.
    """
    for name, _ in sections(RunConfig):
        value = layer.get(name)
        if value is not None and not isinstance(value, Mapping):
            raise ConfigError(
                f"invalid configuration in {source}: {name}: a table of settings, "
                f"not a single value (got {value!r})"
            )


def _family(layer: Mapping[str, Any]) -> Any:
    brain = layer.get("brain")
    return brain.get("family") if isinstance(brain, Mapping) else None


def _layered(base: dict[str, Any], layer: Mapping[str, Any]) -> dict[str, Any]:
    """`layer` over `base`; a layer naming another brain family than `base`'s (GNP when none)
    replaces the brain section: one family's settings do not apply to another's."""
    named = _family(layer)
    if named is not None and named != (_family(base) or DEFAULT_BRAIN):
        base = {key: value for key, value in base.items() if key != "brain"}
    return deep_merge(base, layer)


LEGACY_DEFAULTS: dict[tuple[str, ...], Any] = {
    ("training", "schedule_progress"): "g-over-G",
    ("brain", "evolution", "judgment_pair"): "independent",
}
"""Settings added when their default changed, with the behaviour that files which do not name
them ran with: a stored config is read with these (where their section is), so a resumed old
run goes on as it began."""


def stored_config(text: str) -> RunConfig:
    """A `RunConfig` as stored in a file (JSON), settings it predates taking LEGACY_DEFAULTS.

    Raises:
        ValueError: not JSON (or too large or deep, see `loads_json`), or an invalid config.
    """
    data = loads_json(text, ValueError, "the stored config")
    if not isinstance(data, dict):
        raise ValueError("a stored config is a JSON object")
    data = layout_2(data)  # every file before issue #46 is in layout 1
    for (*where, key), value in LEGACY_DEFAULTS.items():
        part: Any = data
        for section in where:
            part = part.get(section) if isinstance(part, dict) else None
        if isinstance(part, dict):
            part.setdefault(key, value)
    return RunConfig.model_validate(data)


def build_config(*layers: Mapping[str, Any], source: str = "configuration") -> RunConfig:
    """Validate nested dicts merged left to right (later layers win) into a `RunConfig`. Each
    layer may be in either layout (app/settings/layouts.py): it is moved to layout 2 first.

    Raises:
        ConfigError: naming every bad field, its problem and the value given.
    """
    merged: dict[str, Any] = {}
    for given in layers:
        layer = layout_2(given)
        _check_tables(layer, source)
        merged = _layered(merged, layer)
    merged = read_arena_paths(merged)  # user input: arena files are read here, and only here
    try:
        return RunConfig.model_validate(merged)
    except ValidationError as error:
        raise ConfigError(_format_errors(error, source)) from None


def read_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file into a dict: a regular file of at most `MAX_TEXT_BYTES`, with one line
    for a missing, special, too large or malformed file.

    Raises:
        ConfigError: naming the file and the problem.
    """
    what = "config file"
    return loads_toml(read_text(path, ConfigError, what), ConfigError, f"{what} {path}")


def load_preset(name: str) -> RunConfig:
    """A shipped preset as a validated `RunConfig`."""
    return build_config(preset_layer(name), source=f"preset {name!r}")


def load_config(path: str | Path) -> RunConfig:
    """A TOML config file (missing settings take the thesis's defaults)."""
    return build_config(read_toml(path), source=str(path))


def to_toml(config: RunConfig) -> str:
    """Render a config as TOML (unset optional values are left out), readable by `load_config`."""
    lines = [f"seed = {config.seed}"]
    for section, model in config:
        if isinstance(model, BaseModel):
            values = model.model_dump()
            if "arena" in values:  # a shipped arena's name, else an inline table
                values["arena"] = _Rendered(toml_arena(model.arena))  # type: ignore[attr-defined]
            _toml_table(lines, section, values)
    return "\n".join(lines) + "\n"


class _Rendered(str):
    """A value already written as TOML."""


def _toml_table(lines: list[str], name: str, values: dict[str, Any]) -> None:
    lines.append(f"\n[{name}]")
    tables = []
    for key, value in values.items():
        if isinstance(value, dict):  # a nested model: its own table after this one's keys
            tables.append((key, value))
            continue
        if value is None:
            continue
        if isinstance(value, _Rendered):
            rendered = str(value)
        elif isinstance(value, bool):
            rendered = "true" if value else "false"
        elif isinstance(value, str):
            rendered = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
        elif isinstance(value, tuple | list):
            rendered = "[" + ", ".join(str(v) for v in value) + "]"
        else:
            rendered = repr(value)
        lines.append(f"{key} = {rendered}")
    for key, value in tables:
        _toml_table(lines, f"{name}.{key}", value)


def train_settings() -> tuple[Setting, ...]:
    """What `gnp-lab train` and the dashboard's Train tab set, read from the models: the seed
    and every section's scalar settings, the implementation phase's excepted (`implement`
    sets those); of the brain, the default family's (GNP's; another's: `--brain`, `--set`)."""
    found = list(settings_of(RunConfig))
    for name, model in sections(RunConfig):
        if name == "brain":
            brain = settings_model(DEFAULT_BRAIN)
            assert brain is not None
            for part, section in sections(brain):
                found += settings_of(section, ("brain", part))
        elif name != "implementation":
            found += settings_of(model, (name,))
    return tuple(found)


def implement_settings() -> tuple[Setting, ...]:
    """The implementation phase's scalar settings, for `gnp-lab implement`."""
    return settings_of(ImplementationSettings, ("implementation",))
