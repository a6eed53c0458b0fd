"""The run store: layout, reader API, checkpoint slots, names, foreign and corrupt files."""

from __future__ import annotations

import json
import shutil
import threading
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from lab_fixtures import file_digest, tiny_config

import gnp
from app.brains.gnp_brain import initial_population
from app.brains.net_settings import NetSettings
from app.brains.registry import family_of
from app.settings.loading import build_config
from app.store import (
    SCHEMA_VERSION,
    RunFileError,
    RunReader,
    RunWriter,
    list_runs,
    new_run_path,
    resolve_run,
    run_name,
)
from sim import TERM_NAMES


def test_finished_run_is_self_describing(finished_run: Path) -> None:
    config = tiny_config()
    with h5py.File(finished_run, "r") as handle:  # a finished run opens without SWMR too
        assert handle.attrs["format"] == "gnp-lab-run"
        assert handle.attrs["schema_version"] == SCHEMA_VERSION
        assert handle.attrs["seed"] == config.seed
        assert json.loads(handle.attrs["config"])["training"]["population"] == 12
        assert "generations/*_fitness" in json.loads(handle.attrs["units"])
        assert list(handle["generations/best_terms"].attrs["columns"]) == list(TERM_NAMES)
    with RunReader(finished_run) as run:
        assert run.config == config
        assert run.finished and run.generations_done == 3
        history = run.history()
        assert history.fitness.shape == (3, 12)
        # best, mean and std are those of the stored per-individual fitness
        assert np.array_equal(history.best_fitness, history.fitness.max(axis=1))
        assert np.allclose(history.mean_fitness, history.fitness.mean(axis=1))
        assert np.allclose(history.std_fitness, history.fitness.std(axis=1))
        assert np.array_equal(history.best_index, history.fitness.argmax(axis=1))
        assert np.array_equal(history.best_terms["reward"], history.best_fitness)
        assert set(history.mean_terms) == set(TERM_NAMES)
        family = family_of(run.config)
        cfg, best = family.graph_config, family.best(run, 1)
        assert cfg == config.brain.controller.gnp_config()
        assert best.size == 1
        gnp.check_population(cfg, best)
        assert np.array_equal(run.best_genome_arrays(-1)["q_ss"], run.best_genome_arrays(2)["q_ss"])
        with pytest.raises(RunFileError, match="generation 3 is not complete"):
            family.best(run, 3)


def test_half_written_checkpoint_is_never_used(tmp_path: Path) -> None:
    config = tiny_config()
    pop = gnp.population_to_arrays(initial_population(config))
    other = {name: values.copy() for name, values in pop.items()}
    other["speed"][:] = 3
    path = tmp_path / "run.h5"
    writer = RunWriter.create(path, family_of(config).run_template())
    writer.write_checkpoint(1, pop)
    writer.write_checkpoint(2, other)
    with RunReader(path) as run:
        generation, arrays = run.checkpoint() or (None, {})
        assert generation == 2 and np.all(arrays["speed"] == 3)
    # The next checkpoint goes to the other slot; a crash before its pointer is written
    # (simulated: the slot is overwritten, the pointer is not) leaves the previous one intact.
    writer._file["checkpoint/slot0/speed"][...] = -7
    writer._file.flush()
    with RunReader(path) as run:
        generation, arrays = run.checkpoint() or (None, {})
        assert generation == 2 and np.all(arrays["speed"] == 3)
    writer.close()


def test_create_refuses_an_existing_file(finished_run: Path) -> None:
    before = file_digest(finished_run)
    with pytest.raises(RunFileError, match="already exists"):
        RunWriter.create(finished_run, family_of(tiny_config()).run_template())
    assert file_digest(finished_run) == before


def test_foreign_and_corrupt_files(tmp_path: Path, finished_run: Path) -> None:
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as handle:
        handle["x"] = np.arange(3)
    with pytest.raises(RunFileError, match="not a gnp-lab run"):
        RunReader(foreign)
    text = tmp_path / "text.h5"
    text.write_text("hello")
    with pytest.raises(RunFileError, match="not an HDF5 file"):
        RunReader(text)
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(finished_run.read_bytes()[:3000])
    with pytest.raises(RunFileError, match="truncated"):
        RunReader(truncated)
    with pytest.raises(RunFileError, match="not found"):
        RunReader(tmp_path / "missing.h5")


def test_a_file_that_reaches_its_end_while_being_opened_is_read(
    tmp_path: Path, finished_run: Path
) -> None:
    """A live writer's file can end, for a moment, before the end its superblock names (space
    allocated, data not yet written); a reader waits for it instead of calling it truncated."""
    whole = finished_run.read_bytes()
    growing = tmp_path / "growing.h5"
    growing.write_bytes(whole[:3000])

    def write_the_rest() -> None:
        with growing.open("ab") as handle:
            handle.write(whole[3000:])

    rest = threading.Timer(0.1, write_the_rest)
    rest.start()
    try:
        with RunReader(growing) as run, RunReader(finished_run) as original:
            assert run.generations_done == original.generations_done == 3
            np.testing.assert_array_equal(
                run.history().best_fitness, original.history().best_fitness
            )
    finally:
        rest.join()


def test_a_run_missing_a_dataset_is_a_run_file_error(tmp_path: Path, finished_run: Path) -> None:
    broken = tmp_path / "broken.h5"
    shutil.copy(finished_run, broken)
    with h5py.File(broken, "a") as handle:
        del handle["generations/fitness"]
    with pytest.raises(RunFileError, match="generations/fitness is missing"):
        RunReader(broken)  # checked against the layout when opened (issue #47)
    (summary,) = list_runs(tmp_path)  # the listing reports it instead of failing
    assert summary.name == "broken"
    assert summary.error is not None and "fitness is missing" in summary.error


def test_list_and_resolve(tmp_path: Path, finished_run: Path) -> None:
    shutil.copy(finished_run, tmp_path / "good.h5")
    (tmp_path / "bad.h5").write_text("not hdf5")
    runs = {s.name: s for s in list_runs(tmp_path)}
    assert runs["good"].error is None and runs["good"].finished
    assert runs["good"].generations_done == runs["good"].generations == 3
    assert runs["bad"].error is not None and "not an HDF5 file" in runs["bad"].error
    assert resolve_run(tmp_path, "good") == tmp_path / "good.h5"
    assert resolve_run(tmp_path, "good.h5") == tmp_path / "good.h5"
    with pytest.raises(RunFileError, match="no run named"):
        resolve_run(tmp_path, "missing")
    assert list_runs(tmp_path / "nowhere") == []


def test_run_names_hold_the_brains_stem_seed_and_utc_time(tmp_path: Path) -> None:
    config = tiny_config()  # CS, fuzzy, seed 7
    stem = family_of(config).file_stem
    now = datetime(2026, 1, 2, 3, 4, 5, tzinfo=UTC)
    assert run_name(stem, config.seed, now) == "CS-fuzzy-seed7-20260102T030405Z"
    # 23:04:05 on New Year's Eve at UTC−5 is 04:04:05 UTC the next day (and year).
    new_york = datetime(2025, 12, 31, 23, 4, 5, tzinfo=timezone(timedelta(hours=-5)))
    assert run_name(stem, config.seed, new_york) == "CS-fuzzy-seed7-20260101T040405Z"
    crisp = build_config(config.model_dump(), {"controller": {"method": "BS", "fuzzy": False}})
    assert run_name(family_of(crisp).file_stem, 12, now) == "BS-crisp-seed12-20260102T030405Z"
    neat = config.model_copy(update={"brain": NetSettings(family="neat")})
    assert run_name(family_of(neat).file_stem, 7, now) == "neat-seed7-20260102T030405Z"
    # A name already taken gets the first free copy number.
    first = new_run_path(tmp_path, stem, 7, now)
    assert first == tmp_path / "CS-fuzzy-seed7-20260102T030405Z.h5"
    first.touch()
    second = new_run_path(tmp_path, stem, 7, now)
    assert second == tmp_path / "CS-fuzzy-seed7-20260102T030405Z-2.h5"
    second.touch()
    assert new_run_path(tmp_path, stem, 7, now).name == "CS-fuzzy-seed7-20260102T030405Z-3.h5"


@given(
    st.text(min_size=1, max_size=12).flatmap(
        lambda s: st.sampled_from([f"{s}/x", f"../{s}", f"x\\{s}", f".{s}", "/etc/passwd", ".."])
    )
)
def test_names_with_a_path_are_refused(name: str) -> None:
    with pytest.raises(RunFileError, match="plain file name"):
        resolve_run("saved_runs", name)
