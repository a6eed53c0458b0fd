"""The `train` and `implement` options that set a run's settings, built from the models' fields,
and the few options that several subcommands share (`--runs-dir`, a run's name, `--quiet`).

Each scalar setting becomes `--field-name` (a few keep the shorter names the CLI always had);
its help is the field's description, unit, range and default, and its value is checked by
building the model (`build_config`), so a bad value ends in the model's one-line message.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from app.settings.fields import Setting

OPTION_NAMES = {
    "training.noise_sigma": "--noise",
    "implementation.noise_sigma": "--noise",
    "implementation.fault_mode": "--mode",
    "implementation.broken_sensors": "--break",
}
"""Settings whose option is not `--field-name`: the names the CLI had before options were
generated, kept so that every documented command still works."""

NEGATIONS = {"brain.controller.fuzzy": "--crisp"}
"""A switch's "off" option where it is not `--no-field-name`."""

OPTIONS_DEST = "setting_options"
"""Where a parser's namespace lists the setting options it was built with."""


@dataclass(frozen=True)
class SettingOption:
    """A command-line option that sets one setting."""

    setting: Setting
    flag: str  # e.g. --population

    @property
    def dest(self) -> str:
        return f"setting:{self.setting.key}"

    @property
    def off_flag(self) -> str:
        """A switch's "off" option: `--no-field-name`, or its `NEGATIONS` name."""
        return NEGATIONS.get(self.setting.key, f"--no-{self.flag.removeprefix('--')}")

    def given_as(self, value: Any) -> str:
        """The option as given on the command line for `value`: `--crisp` for fuzzy off."""
        return self.off_flag if self.setting.kind == "bool" and value is False else self.flag


def int_list(text: str) -> tuple[int, ...]:
    """`2,3` → (2, 3); `none` or nothing → ()."""
    text = text.strip()
    if text.lower() in ("", "none"):
        return ()
    try:
        return tuple(int(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected sensor numbers separated by commas, like 2,3 (got {text!r})"
        ) from None


_TYPES: dict[str, Callable[[str], Any]] = {"int": int, "float": float, "ints": int_list}
_METAVARS = {"int": "N", "float": "X", "ints": "N,N"}


def add_setting_options(
    parser: argparse.ArgumentParser, settings: Sequence[Setting], show_default: bool
) -> tuple[SettingOption, ...]:
    """Add one option per setting to `parser` (argparse refuses a name given twice).

    Args:
        parser: a command's parser.
        settings: what the options set.
        show_default: put the model's default in the help (off where unset options take
            another source's values, e.g. a stored run's).
    """
    options = []
    for setting in settings:
        flag = OPTION_NAMES.get(setting.key, "--" + setting.name.replace("_", "-"))
        option = SettingOption(setting, flag)
        text = setting.help(show_default).replace("%", "%%")
        if setting.kind == "bool":
            group = parser.add_mutually_exclusive_group()
            group.add_argument(flag, dest=option.dest, action="store_true", default=None, help=text)
            group.add_argument(
                option.off_flag, dest=option.dest, action="store_false", help=f"not {flag}"
            )
        elif setting.kind == "choice":
            parser.add_argument(flag, dest=option.dest, choices=setting.choices, help=text)
        else:
            parser.add_argument(
                flag,
                dest=option.dest,
                type=_TYPES[setting.kind],
                metavar=_METAVARS[setting.kind],
                help=text,
            )
        options.append(option)
    parser.set_defaults(**{OPTIONS_DEST: tuple(options)})
    return tuple(options)


def given_options(args: argparse.Namespace) -> dict[SettingOption, Any]:
    """The setting options given on the command line, with their values."""
    options: tuple[SettingOption, ...] = getattr(args, OPTIONS_DEST, ())
    values = {option: getattr(args, option.dest) for option in options}
    return {option: value for option, value in values.items() if value is not None}


def given_settings(args: argparse.Namespace) -> dict[tuple[str, ...], Any]:
    """{setting path: value} of the setting options given on the command line."""
    return {option.setting.path: value for option, value in given_options(args).items()}


RUNS_DIR = "saved_runs"
"""The folder of run files when `--runs-dir` is not given."""


def add_runs_dir(parser: argparse.ArgumentParser) -> None:
    """`--runs-dir DIR` (default `RUNS_DIR`)."""
    parser.add_argument("--runs-dir", default=RUNS_DIR, help="folder of run files")


def add_run_name(parser: argparse.ArgumentParser) -> None:
    """The positional `RUN`: a run's name in `--runs-dir`."""
    parser.add_argument("run", metavar="RUN", help="run name in --runs-dir")


def add_quiet(parser: argparse.ArgumentParser) -> None:
    """`--quiet`: no progress bar."""
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
