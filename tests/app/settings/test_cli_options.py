"""`train` and `implement` options built from the settings' models: names, help, bounds."""

from __future__ import annotations

import argparse
import tomllib

import pytest
from pydantic import BaseModel, Field

from app.cli import main
from app.cli.parser import build_parser
from app.settings.cli_options import (
    OPTION_NAMES,
    add_setting_options,
    given_settings,
)
from app.settings.fields import Setting, about, settings_of
from app.settings.loading import implement_settings, train_settings


def _flag(setting: Setting) -> str:
    return OPTION_NAMES.get(setting.key, "--" + setting.name.replace("_", "-"))


def _words(text: str) -> str:
    """Text without its white space: argparse wraps lines at spaces and hyphens."""
    return "".join(text.split())


def test_every_train_setting_is_an_option_whose_help_is_the_model(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["train", "--help"]) == 0
    shown = _words(capsys.readouterr().out)
    settings = train_settings()
    keys = {s.key for s in settings}
    # Every section of a run but the implementation phase's (and the optional neural one).
    assert {"seed", "brain.controller.method", "training.population", "reward.c_from"} <= keys
    assert "brain.evolution.p_mutation" in keys and not any(
        k.startswith("implementation") for k in keys
    )
    for setting in settings:
        assert f"[{_flag(setting)}" in shown
        assert _words(setting.help()) in shown, setting.key
    assert (
        _words("individuals [count]; 2..100000 (default 300)") in shown
    )  # hand-written: the field


def _outside(setting: Setting) -> list[str]:
    """Values just outside a setting's bounds, as typed."""
    values = []
    step = setting.step()
    if setting.low is not None:
        values.append(str(setting.low if setting.low_open else setting.low - step))
    if setting.high is not None:
        values.append(str(setting.high if setting.high_open else setting.high + step))
    return values


BOUNDED = [s for s in train_settings() if s.kind in ("int", "float") and _outside(s)]


@pytest.mark.parametrize("setting", BOUNDED, ids=lambda s: s.key)
def test_a_value_outside_a_fields_bounds_is_one_error_line(
    setting: Setting, capsys: pytest.CaptureFixture[str]
) -> None:
    for value in _outside(setting):
        assert main(["train", _flag(setting), value, "--print-config"]) == 1
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("gnp-lab: error: "), captured.err
        assert f"{setting.key}: Input should be" in lines[0]
        assert captured.out == ""


def test_the_seed_reaches_the_models_bound(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["train", "--seed", str(2**63 - 1), "--print-config"]) == 0
    assert tomllib.loads(capsys.readouterr().out)["seed"] == 2**63 - 1


def test_the_rewards_c_source_is_an_option_and_a_set(capsys: pytest.CaptureFixture[str]) -> None:
    (setting,) = [s for s in train_settings() if s.key == "reward.c_from"]
    assert setting.choices == ("true", "observed") and setting.default == "true"
    for argv in (["--c-from", "observed"], ["--set", "reward.c_from=observed"]):
        assert main(["train", *argv, "--print-config"]) == 0
        assert tomllib.loads(capsys.readouterr().out)["reward"]["c_from"] == "observed"
    assert main(["train", "--c-from", "measured"]) == 2
    assert "invalid choice: 'measured'" in capsys.readouterr().err


def test_options_keep_their_historic_names() -> None:
    train = build_parser().parse_args(
        ["train", "--noise", "20", "--crisp", "--method", "BS", "--steps", "30", "--seed", "3"]
    )
    assert given_settings(train) == {
        ("training", "noise_sigma"): 20.0,
        ("brain", "controller", "fuzzy"): False,
        ("brain", "controller", "method"): "BS",
        ("training", "steps"): 30,
        ("seed",): 3,
    }
    argv = ["implement", "r", "--break", "2,3", "--mode", "stuck", "--noise", "5", "--seed", "4"]
    assert given_settings(build_parser().parse_args(argv)) == {
        ("implementation", "broken_sensors"): (2, 3),
        ("implementation", "fault_mode"): "stuck",
        ("implementation", "noise_sigma"): 5.0,
        ("implementation", "seed"): 4,
    }
    assert {s.key for s in implement_settings()} >= {"implementation.epsilon_max"}


class _Lamp(BaseModel):
    """A model nobody ships: what one new field gives the CLI."""

    watts: float = Field(
        default=60.0, gt=0.0, le=250.0, description="bulb power", json_schema_extra=about("W")
    )


def test_a_new_field_is_a_new_option_with_its_facts() -> None:
    parser = argparse.ArgumentParser()
    add_setting_options(parser, settings_of(_Lamp, ("lamp",)), show_default=True)
    assert _words("bulb power [W]; > 0, ≤ 250 (default 60)") in _words(parser.format_help())
    assert given_settings(parser.parse_args(["--watts", "75"])) == {("lamp", "watts"): 75.0}
    assert given_settings(parser.parse_args([])) == {}
