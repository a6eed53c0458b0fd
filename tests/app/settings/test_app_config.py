"""Run configuration: thesis presets, validation messages, TOML round trips, CLI layering."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.brains.learning import schedules
from app.cli.parser import build_parser
from app.cli.train import config_from_args
from app.settings.config import PRESET_NAMES, ConfigError, RunConfig
from app.settings.loading import build_config, load_config, load_preset, to_toml
from gnp.config import TASK_SETTINGS


def test_defaults_are_the_thesis_table_2_4() -> None:
    config = RunConfig()
    assert config.training.population == 300
    assert config.training.steps == 1000
    assert (config.training.epsilon, config.training.alpha) == (0.1, 0.1)
    assert config.brain.controller.gamma == 0.9
    assert (config.brain.controller.n_judgment, config.brain.controller.n_processing) == (40, 20)
    assert config.brain.evolution.split(300) == (1, 120, 179)
    assert config.brain.evolution.tournament_size == 7
    assert (config.brain.evolution.p_crossover, config.brain.evolution.p_mutation) == (0.1, 0.01)
    assert config.implementation.steps == 3000
    assert config.implementation.fault_step == 500


def test_presets_match_the_thesis_tables() -> None:
    ch2 = load_preset("thesis-ch2")
    assert (ch2.brain.controller.method, ch2.brain.controller.sub_nodes) == ("RL", 2)
    ch3 = load_preset("thesis-ch3")
    assert (
        ch3.brain.controller.method,
        ch3.brain.controller.sub_nodes,
        ch3.brain.controller.n_branch,
    ) == (
        "BS",
        2,
        2,
    )
    # Table 3.1: the RL baseline of chapter 3 uses 4 sub nodes.
    ch3_rl = build_config(
        ch3.model_dump(exclude={"controller": {"n_sub"}}), {"controller": {"method": "RL"}}
    )
    assert ch3_rl.brain.controller.gnp_config().n_sub == 4
    ch4 = load_preset("thesis-ch4")
    eps, alpha = schedules(ch4.training)
    assert (eps.max, eps.min, alpha.max, alpha.min, eps.n) == (0.15, 0.01, 0.70, 0.10, 1.0)
    eps_t, alpha_t = schedules(ch4.implementation)
    assert (eps_t.max, eps_t.min, alpha_t.max, alpha_t.min) == (0.015, 0.0, 0.15, 0.0)
    assert (ch4.implementation.epsilon, ch4.implementation.alpha) == (0.01, 0.10)
    ch5 = load_preset("thesis-ch5")
    assert ch5.brain.controller.method == "CS"
    assert (ch5.training.steps, ch5.training.redraw_every, ch5.training.noise_sigma) == (
        2000,
        500,
        50.0,
    )
    assert ch5.implementation.noise_sigma == 50.0
    for name in PRESET_NAMES:
        assert load_preset(name).brain.controller.fuzzy


@pytest.mark.parametrize(
    ("layer", "expected"),
    [
        ({"training": {"population": 1}}, "training.population: Input should be greater than"),
        ({"training": {"noise_sigma": -3}}, "training.noise_sigma"),
        ({"training": {"popsize": 10}}, "training.popsize: unknown setting"),
        ({"controller": {"method": "XX"}}, "brain.controller.method"),
        ({"brain": {"controller": {"n_judgment": 3}}}, "brain.controller.n_judgment: Input"),
        ({"brain": {"family": "cmaes", "hidden": 0}}, "brain.hidden: Input should be greater"),
        ({"brain": {"family": "neat", "controller": {}}}, "brain.controller: unknown setting"),
        ({"implementation": {"broken_sensors": [8]}}, "sensors are numbered 0..7"),
        ({"implementation": {"broken_sensors": [2, 2]}}, "listed twice"),
        ({"training": {"epsilon_min": 0.9}}, "epsilon_min (0.9) must not exceed epsilon_max"),
        (
            {"brain": {"controller": {"judgment_branches": 3}}},  # fuzzy by default
            "judgment_branches = 3 needs crisp judgment (fuzzy = false)",
        ),
        ({"brain": {"controller": {"fuzzy": False, "judgment_branches": 9}}}, "less than or equal"),
        (
            {"implementation": {"steps": 100, "fault_step": 100, "broken_sensors": [1]}},
            "fault_step (100) must be below steps (100)",
        ),
    ],
)
def test_bad_values_name_the_field(layer: dict, expected: str) -> None:
    with pytest.raises(ConfigError) as caught:
        build_config(layer, source="test")
    assert expected in str(caught.value)
    assert "\n" not in str(caught.value)


def test_config_files(tmp_path: Path) -> None:
    good = tmp_path / "good.toml"
    good.write_text('seed = 3\n[training]\npopulation = 20\n[controller]\nmethod = "BS"\n')
    config = load_config(good)
    assert (config.seed, config.training.population, config.brain.controller.method) == (
        3,
        20,
        "BS",
    )
    assert config.training.steps == 1000  # unset settings keep the thesis's defaults
    broken = tmp_path / "broken.toml"
    broken.write_text("[training\npopulation = 20\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(broken)
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "missing.toml")
    with pytest.raises(ConfigError, match="unknown preset"):
        load_preset("thesis-ch9")


@settings(max_examples=30, deadline=None)
@given(
    population=st.integers(2, 1000),
    noise=st.floats(0, 1023, allow_nan=False),
    method=st.sampled_from(["RL", "BS", "CS"]),
    sensors=st.sets(st.integers(0, 7), max_size=8),
    n_sub=st.one_of(st.none(), st.integers(1, 8)),
)
def test_toml_round_trip(
    population: int, noise: float, method: str, sensors: set[int], n_sub: int | None
) -> None:
    config = build_config(
        {
            "controller": {"method": method, "n_sub": n_sub},
            "training": {"population": population, "noise_sigma": noise},
            "implementation": {"broken_sensors": sorted(sensors)},
        }
    )
    assert build_config(tomllib.loads(to_toml(config))) == config


def test_cli_layers_preset_then_file_then_options(tmp_path: Path) -> None:
    file = tmp_path / "c.toml"
    file.write_text("[training]\nsteps = 111\ngenerations = 7\n")
    args = build_parser().parse_args(
        [
            "train",
            "--preset",
            "thesis-ch5",
            "--config",
            str(file),
            "--generations",
            "9",
            "--crisp",
            "--set",
            "training.redraw_every=50",
            "--set",
            "implementation.fault_mode=stuck",
        ]
    )
    config = config_from_args(args)
    assert config.training.noise_sigma == 50.0  # from the preset
    assert config.training.steps == 111  # the file beats the preset
    assert config.training.generations == 9  # options beat the file
    assert config.training.redraw_every == 50
    assert config.implementation.fault_mode == "stuck"
    assert config.brain.controller.fuzzy is False


def test_a_stored_config_that_predates_a_setting_keeps_its_old_behaviour() -> None:
    from app.settings.config import RunConfig
    from app.settings.loading import stored_config

    new = RunConfig()
    assert new.training.schedule_progress == "last-generation-min"
    assert new.brain.evolution.judgment_pair == "joint"
    assert stored_config(new.model_dump_json()) == new  # named settings are kept
    old = json.loads(new.model_dump_json())
    del old["training"]["schedule_progress"], old["brain"]["evolution"]["judgment_pair"]
    legacy = stored_config(json.dumps(old))
    assert legacy.training.schedule_progress == "g-over-G"
    assert legacy.brain.evolution.judgment_pair == "independent"


@pytest.mark.parametrize(
    "name", ["fuzzy", "n_judgment", "n_processing", "n_branch", "gamma", *TASK_SETTINGS]
)
def test_the_controllers_settings_are_gnps_own(name: str) -> None:
    import gnp
    from app.brains.gnp_settings import ControllerSettings
    from app.settings.fields import read_setting

    lab, brain = read_setting(ControllerSettings, name), read_setting(gnp.GnpConfig, name)
    assert lab is not None and brain is not None
    assert (lab.default, lab.description) == (brain.default, brain.description)
    if brain.low is not None:  # the lab may narrow gnp's range, never widen it
        assert lab.low is not None and lab.low >= brain.low
    if brain.high is not None:
        assert lab.high is not None and lab.high <= brain.high
