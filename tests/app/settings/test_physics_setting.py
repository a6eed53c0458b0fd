"""The run setting `training.physics`: chosen in configs, the CLI and experiment specs, recorded
in run files, passed to every world of both phases."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lab_fixtures import assert_same_data, tiny_config

import sim
from app.cli.parser import build_parser
from app.cli.train import config_from_args
from app.experiments.spec_loading import load_shipped, parse
from app.phases.implementation import implement
from app.phases.training import train
from app.settings.config import ConfigError, RunConfig
from app.settings.loading import build_config, stored_config
from app.store import RunReader


def test_the_default_is_pymunk_and_old_run_files_read_as_pymunk() -> None:
    assert RunConfig().training.physics == "pymunk"
    old = json.loads(RunConfig().model_dump_json())
    del old["training"]["physics"]  # a run file written before the setting
    assert stored_config(json.dumps(old)) == RunConfig()
    assert RunConfig.model_validate_json(json.dumps(old)) == RunConfig()


def test_a_bad_physics_names_the_field() -> None:
    with pytest.raises(ConfigError, match=r"training\.physics: .*'pymunk' or 'analytic'.*box2d"):
        build_config({"training": {"physics": "box2d"}})


def test_the_cli_sets_it() -> None:
    args = build_parser().parse_args(["train", "--set", "training.physics=analytic"])
    assert config_from_args(args).training.physics == "analytic"


def _spec(arm_config: dict[str, Any], scale_config: dict[str, Any]) -> dict[str, Any]:
    return {
        "name": "p",
        "description": "d",
        "source": "s",
        "preset": "quick",
        "arms": [
            {"name": "a", "label": "A", "config": arm_config},
            {"name": "b", "label": "B"},
        ],
        "scales": {"smoke": {"config": scale_config}},
    }


def test_experiment_arms_and_scales_set_it() -> None:
    by_arm = parse(_spec({"training": {"physics": "analytic"}}, {}), "test")
    assert [by_arm.run_config(arm, "smoke", 0).training.physics for arm in "ab"] == [
        "analytic",
        "pymunk",
    ]
    by_scale = parse(_spec({}, {"training": {"physics": "analytic"}}), "test")
    assert {by_scale.run_config(arm, "smoke", 0).training.physics for arm in "ab"} == {"analytic"}
    shipped = load_shipped("physics-equivalence")
    physics = {
        arm.name: shipped.run_config(arm.name, "small", 0).training.physics for arm in shipped.arms
    }
    assert physics == {
        "BS-pymunk": "pymunk",
        "BS-analytic": "analytic",
        "RL-pymunk": "pymunk",
        "RL-analytic": "analytic",
    }


def test_both_phases_run_in_the_chosen_physics_and_the_run_file_records_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The analytic world's poses are pymunk's bit for bit (tests/sim/test_analytic.py), so
    a run and its implementation give the same numbers in either physics."""
    built: list[str] = []
    world_init = sim.World.__init__

    def spy(self: sim.World, *args: Any, **kwargs: Any) -> None:
        world_init(self, *args, **kwargs)
        built.append(self.physics)

    monkeypatch.setattr(sim.World, "__init__", spy)
    paths = {}
    for physics in sim.PHYSICS:
        paths[physics] = tmp_path / f"{physics}.h5"
        built.clear()
        train(tiny_config(generations=2, physics=physics), paths[physics], workers=1)
        assert built and set(built) == {physics}
        with RunReader(paths[physics]) as run:
            assert run.config.training.physics == physics
            settings = run.config.implementation
        built.clear()
        implement(paths[physics], settings, name="fault", workers=1)
        assert built and set(built) == {physics}
    assert_same_data(paths["pymunk"], paths["analytic"])


def test_the_dashboards_implementation_phase_keeps_the_runs_physics(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """It ran in pymunk whatever the run's physics (issue #33); it reads the run's worlds as
    `implement` does (`app.phases.implementation.implementation_of`), and gives its numbers."""
    from app.dashboard.implementation_job import ImplementationRequest, implement_run

    path = tmp_path / "analytic.h5"
    train(tiny_config(generations=1, physics="analytic"), path, workers=1)
    built: list[str] = []
    world_init = sim.World.__init__

    def spy(self: sim.World, *args: Any, **kwargs: Any) -> None:
        world_init(self, *args, **kwargs)
        built.append(self.physics)

    monkeypatch.setattr(sim.World, "__init__", spy)
    request = ImplementationRequest(path, (2, 3), "dead", 30, 60, 1, "fixed")
    result = implement_run(request)
    assert built and set(built) == {"analytic"}
    with RunReader(path) as run:
        settings = request.settings(run.config.implementation)
    stored = implement(path, settings, name="same", workers=1)
    np.testing.assert_array_equal(result.trial_mean_reward, stored.trial_mean_reward)
