"""The layout table is the file: every dataset, shape, type, storage and unit comes from it."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from lab_fixtures import tiny_config

from app.brains.registry import family_of
from app.loop.recording import Trajectory
from app.settings.config import ImplementationSettings
from app.settings.layouts import layout_1
from app.store import Implementation, RunReader, RunTemplate, RunWriter, add_implementation, schema
from app.store.schema import (
    IMPLEMENTATION_LAYOUT,
    RUN_LAYOUT,
    Dataset,
    Placed,
    Unit,
    implementation_dims,
    place,
)
from sim import TERM_NAMES

DEMO = Path(__file__).parents[3] / "saved_runs" / "demo.h5"


def _datasets(group: h5py.Group) -> dict[str, h5py.Dataset]:
    found: dict[str, h5py.Dataset] = {}
    group.visititems(
        lambda name, obj: found.__setitem__(name, obj) if isinstance(obj, h5py.Dataset) else None
    )
    return found


def _assert_matches(group: h5py.Group, expected: list[Placed]) -> None:
    """`group` holds exactly the `expected` datasets, each as its row says."""
    found = _datasets(group)
    assert sorted(found) == sorted(spec.path for spec in expected)
    for spec in expected:
        dataset, row = found[spec.path], spec.row
        assert dataset.shape == spec.shape, spec.path
        assert dataset.dtype == spec.dtype, spec.path
        chunked = row.chunk_rows is not None and 0 not in spec.shape and row.initial is None
        assert (dataset.chunks is not None) == chunked, spec.path
        assert dataset.compression == ("gzip" if row.compress and chunked else None), spec.path
        if row.fill is not None:
            assert math.isclose(dataset.fillvalue, row.fill) or (
                math.isnan(row.fill) and math.isnan(dataset.fillvalue)
            ), spec.path
        if row.shape[-1:] == ("terms",):
            assert list(dataset.attrs["columns"]) == list(TERM_NAMES), spec.path


def test_a_new_run_file_holds_exactly_the_table(tmp_path: Path) -> None:
    template = family_of(tiny_config()).run_template()
    path = tmp_path / "run.h5"
    RunWriter.create(path, template).close()
    with h5py.File(path, "r") as handle:
        expected = place(RUN_LAYOUT, template.dims(), template.arrays())
        _assert_matches(handle, expected)
        # Named axes resolve to the config: G = 3 generations of P = 12, T = 60 steps.
        shapes = {spec.path: spec.shape for spec in expected}
        assert shapes["generations/fitness"] == (3, 12)
        assert shapes["elite/poses"] == (1, 60, 3)
        assert shapes["genomes/best/q_ss"] == (3, *template.genome["q_ss"].shape[1:])
        assert handle["generations/fitness"].chunks == (3, 12)  # min(G, 8 rows)
        assert handle["checkpoint/slot0/conn"].chunks == handle["checkpoint/slot0/conn"].shape
        # Values written at creation.
        assert list(handle["progress/checkpoint"][()]) == [-1, 0]
        assert handle["elite/generation"][()] == -1
        assert np.isnan(handle["generations/best_fitness"][()]).all()
        assert (handle["generations/best_index"][()] == -1).all()


def test_the_units_attribute_comes_from_the_table(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    template = family_of(tiny_config()).run_template()
    RunWriter.create(tmp_path / "run.h5", template).close()
    with h5py.File(tmp_path / "run.h5", "r") as handle:
        units = json.loads(handle.attrs["units"])
    rows = (*RUN_LAYOUT, *IMPLEMENTATION_LAYOUT)
    assert units == {row.unit.covers: row.unit.text for row in rows if row.unit is not None}
    assert units["generations/*_fitness"] == "mean reward per step (Eq. 2.8), 0..1"
    # A new row with a new unit: the file gets the dataset and the unit, nothing else to edit.
    furlongs = Unit("extra/distance", "furlongs")
    extra = Dataset("extra/distance", ("generations",), "f4", unit=furlongs)
    monkeypatch.setattr(schema, "RUN_LAYOUT", (*RUN_LAYOUT, extra))
    RunWriter.create(tmp_path / "extra.h5", template).close()
    with h5py.File(tmp_path / "extra.h5", "r") as handle:
        assert handle["extra/distance"].shape == (3,)
        assert handle["extra/distance"].dtype == np.float32
        assert json.loads(handle.attrs["units"])["extra/distance"] == "furlongs"


def an_implementation(steps: int = 7, trials: int = 3, recorded: int = 2) -> Implementation:
    rng = np.random.default_rng(0)
    lives = Trajectory(
        poses=rng.random((recorded, steps, 3)),
        readings=rng.random((recorded, steps, 8)),
        observations=rng.random((recorded, steps, 8)),
        commands=rng.random((recorded, steps, 2)),
        terms={t: rng.random((recorded, steps)) for t in TERM_NAMES},
        trace={
            "node": rng.integers(0, 9, (recorded, steps, 6), dtype=np.int32),
            "count": rng.integers(0, 6, (recorded, steps), dtype=np.int32),
        },
        start_index=np.arange(recorded),
    )
    return Implementation(
        name="probe",
        settings=ImplementationSettings(),
        generation=2,
        reward_per_step=rng.random(steps),
        trial_mean_reward=rng.random(trials),
        trial_mean_after_fault=rng.random(trials),
        start_index=np.arange(trials) % 10,
        mean_reward=0.5,
        mean_after_fault=0.25,
        trials=lives,
        recorded=np.arange(recorded),
    )


def test_an_implementation_group_holds_the_table(tmp_path: Path, finished_run: Path) -> None:
    path = tmp_path / "run.h5"
    shutil.copy(finished_run, path)
    result = an_implementation()
    add_implementation(path, result)
    with h5py.File(path, "r") as handle:
        one_step = {name: values[:, 0] for name, values in result.trials.trace.items()}
        dims = implementation_dims(steps=7, trials=3, recorded=2)
        expected = place(IMPLEMENTATION_LAYOUT, dims, {"trace": one_step})
        _assert_matches(handle["implementation/probe"], expected)
    with RunReader(path) as run:
        stored = run.implementation("probe")
    assert np.array_equal(stored.reward_per_step, result.reward_per_step)
    assert np.array_equal(stored.trials.trace["node"], result.trials.trace["node"])
    assert np.array_equal(stored.trials.terms["reward"], result.trials.terms["reward"])


def _template_of(run: RunReader) -> RunTemplate:
    """The template a stored run was made from, read back from its own datasets."""
    handle = run.file
    return RunTemplate(
        run.config,
        genome={name: ds[:1] for name, ds in handle["checkpoint/slot0"].items()},
        trace={name: ds[0, :1] for name, ds in handle["elite/trace"].items()},
    )


def test_the_bundled_demo_run_still_loads_and_matches_the_table() -> None:
    with RunReader(DEMO) as run:
        template = _template_of(run)
        _assert_matches(
            run.file, place(RUN_LAYOUT, template.dims(), template.arrays()) + _implementations(run)
        )
        assert run.finished and run.generations_done == run.config.training.generations
        assert len(run.history().best_fitness) == run.generations_done
        elite = run.elite()
        assert elite is not None and elite.poses.shape == (1, run.config.training.steps, 3)
        for name in run.implementation_names():
            stored = run.implementation(name)
            assert stored.trials.poses.shape[1] == len(stored.reward_per_step)
        assert run.implementation_names(), "the demo ships with implementations"


def _implementations(run: RunReader) -> list[Placed]:
    """The table's datasets of every implementation stored in `run`, with their full paths."""
    placed = []
    for name in run.implementation_names():
        group = run.file[f"implementation/{name}"]
        dims = implementation_dims(
            steps=len(group["reward_per_step"]),
            trials=len(group["start_index"]),
            recorded=len(group["recorded"]),
        )
        trace = {field: ds[:, 0] for field, ds in group["trials/trace"].items()}
        for spec in place(IMPLEMENTATION_LAYOUT, dims, {"trace": trace}):
            path = f"implementation/{name}/{spec.path}"
            placed.append(Placed(path, spec.shape, spec.dtype, spec.row))
    return placed


def test_a_run_file_written_before_a_setting_existed_loads_with_its_old_behaviour(
    finished_run: Path, tmp_path: Path
) -> None:
    """A file whose stored config does not name `schedule_progress` and `judgment_pair` ran
    with the behaviour of its time (`LEGACY_DEFAULTS`), not today's defaults; it was written
    in layout 1 (app/settings/layouts.py)."""
    old = tmp_path / "old.h5"
    shutil.copyfile(finished_run, old)
    with h5py.File(old, "r+") as handle:
        config = layout_1(json.loads(handle.attrs["config"]), "gnp")
        del config["training"]["schedule_progress"], config["evolution"]["judgment_pair"]
        handle.attrs["config"] = json.dumps(config)
    with RunReader(old) as run:
        assert run.config.training.schedule_progress == "g-over-G"
        assert run.config.brain.evolution.judgment_pair == "independent"
    with RunReader(finished_run) as run:  # a file of today names both
        assert run.config.training.schedule_progress == "last-generation-min"
        assert run.config.brain.evolution.judgment_pair == "joint"


def test_an_implementation_read_without_its_recorded_trials_keeps_everything_else() -> None:
    with RunReader(DEMO) as run:
        for name in run.implementation_names():
            full, light = run.implementation(name), run.implementation(name, recorded=False)
            assert full.trials.poses.shape[0] > 0
            for field in ("reward_per_step", "trial_mean_reward", "trial_mean_after_fault"):
                np.testing.assert_array_equal(getattr(light, field), getattr(full, field))
            assert (light.settings, light.generation) == (full.settings, full.generation)
            assert (light.mean_reward, light.mean_after_fault) == (
                full.mean_reward,
                full.mean_after_fault,
            )
            assert light.recorded.shape == (0,)
            assert light.trials.poses.shape == (0, *full.trials.poses.shape[1:])
            for field, array in full.trials.trace.items():
                assert light.trials.trace[field].shape == (0, *array.shape[1:])
