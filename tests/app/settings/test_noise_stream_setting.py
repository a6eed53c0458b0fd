"""The run setting `training.noise_stream`: chosen in configs, the CLI and experiment specs,
recorded in run files, passed to every world of both phases (as `training.physics` is)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lab_fixtures import datasets, tiny_config

import sim
from app.cli.parser import build_parser
from app.cli.train import config_from_args
from app.experiments.spec_loading import load_shipped
from app.phases.implementation import implement
from app.phases.training import train
from app.settings.config import ConfigError, RunConfig
from app.settings.loading import build_config, stored_config
from app.store import RunReader


def test_the_default_is_box_muller_and_old_run_files_read_as_it() -> None:
    assert RunConfig().training.noise_stream == "box-muller-v1"
    old = json.loads(RunConfig().model_dump_json())
    del old["training"]["noise_stream"]  # a run file written before the setting
    assert stored_config(json.dumps(old)) == RunConfig()


def test_a_bad_stream_names_the_field() -> None:
    with pytest.raises(ConfigError, match=r"training\.noise_stream: .*'ziggurat-v1'.*polar"):
        build_config({"training": {"noise_stream": "polar"}})


def test_the_cli_sets_it() -> None:
    args = build_parser().parse_args(["train", "--set", "training.noise_stream=ziggurat-v1"])
    assert config_from_args(args).training.noise_stream == "ziggurat-v1"


def test_the_shipped_equivalence_experiment_names_both_streams() -> None:
    spec = load_shipped("noise-stream-equivalence")
    streams = {arm.name: spec.run_config(arm.name, "smoke", 0).training for arm in spec.arms}
    assert {name: t.noise_stream for name, t in streams.items()} == {
        "BS-box-muller": "box-muller-v1",
        "BS-ziggurat": "ziggurat-v1",
    }
    assert {t.physics for t in streams.values()} == {"analytic"}
    assert {t.noise_sigma for t in streams.values()} == {50.0}


def test_both_phases_draw_the_chosen_stream_and_the_run_file_records_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    built: list[str] = []
    world_init = sim.World.__init__

    def spy(self: sim.World, *args: Any, **kwargs: Any) -> None:
        world_init(self, *args, **kwargs)
        built.append(self.noise_stream)

    monkeypatch.setattr(sim.World, "__init__", spy)
    paths = {}
    for stream in sim.NOISE_STREAMS:
        paths[stream] = tmp_path / f"{stream}.h5"
        built.clear()
        config = tiny_config(generations=2, noise_sigma=50.0, physics="analytic")
        config = build_config(config.model_dump(), {"training": {"noise_stream": stream}})
        train(config, paths[stream], workers=1)
        assert built and set(built) == {stream}
        with RunReader(paths[stream]) as run:
            assert run.config.training.noise_stream == stream
            settings = run.config.implementation
        built.clear()
        implement(paths[stream], settings, name="fault", workers=1)
        assert built and set(built) == {stream}
    a, b = (datasets(paths[stream]) for stream in sim.NOISE_STREAMS)
    assert any(not np.array_equal(a[name], b[name]) for name in a)  # other draws, other lives
