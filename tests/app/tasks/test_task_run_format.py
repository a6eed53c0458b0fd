"""A task run is a run file (issue #46 item 2): the lab's one format and writer, the rows of its
kind, its units its own; a task run file of the old format still reads, lists, replays,
exports and resumes (into the run format); a damaged task run is one error line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from lab_fixtures import one_error_line
from legacy_task_files import write_old_task_run

from app.cli import main
from app.phases.generations import Interrupted
from app.settings.families import DEFAULT_BRAIN
from app.store import TASK, RunFileError, RunReader, RunTemplate, file_kind, list_runs
from app.store.schema import (
    EPISODE_RETURN,
    RUN_LAYOUT,
    TASK_RUN_LAYOUT,
    place,
    units_attribute,
)
from app.tasks import TaskRunConfig, TaskSettings, TaskTraining, read_task_run, train_task
from app.tasks.common import is_task_run
from app.tasks.training import replay_task, resume_task


def _config(generations: int = 3) -> TaskRunConfig:
    return TaskRunConfig(
        seed=4,
        task=TaskSettings(id="CartPole-v1"),
        training=TaskTraining(population=6, generations=generations, steps=40),
    )


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished GNP task run of the run format (do not modify: copy it first)."""
    return train_task(_config(), tmp_path_factory.mktemp("whole") / "whole.h5")


def _cut(config: TaskRunConfig, path: Path) -> Path:
    """`config` trained into `path` and stopped after its first generation."""

    def stop_after_one(_summary: object) -> None:
        raise KeyboardInterrupt

    with pytest.raises(Interrupted):
        train_task(config, path, stop_after_one)
    return path


def test_a_task_run_is_a_run_file_of_its_kind_with_its_rows_and_units(whole: Path) -> None:
    with RunReader(whole, TASK) as run:
        handle = run.file
        assert handle.attrs["format"] == "gnp-lab-run" and handle.attrs["kind"] == "task"
        assert "reward_terms" not in handle.attrs
        assert TaskRunConfig.model_validate_json(handle.attrs["config"]) == _config()
        names: set[str] = set()
        handle.visititems(
            lambda name, obj: names.add(name) if isinstance(obj, h5py.Dataset) else None
        )
        slot = handle["checkpoint/slot0"]
        genome = {name: slot[name][:1] for name in slot}
        template = RunTemplate(run.config, genome, {}, task_config=run.task_config)
        assert template.kind == "task"
        expected = place(TASK_RUN_LAYOUT, template.dims(), template.arrays())
        assert names == {spec.path for spec in expected}
        robot_only = ("elite/", "generations/best_terms", "generations/mean_terms")
        assert not any(name.startswith(robot_only) for name in names)
        assert "generations/env_steps" not in {spec.path for spec in RUN_LAYOUT}
        units = json.loads(handle.attrs["units"])
        assert units == json.loads(units_attribute("task"))
        assert units["generations/*_fitness"] == EPISODE_RETURN
        assert units["generations/env_steps"] == "env steps"
        assert not any(key.startswith(("elite", "implementation")) for key in units)
        assert run.finished and run.elite() is None and run.term_names == ()
        history = run.history()
        assert history.best_terms == {} and history.env_steps is not None
        assert (history.env_steps > 0).all()
        np.testing.assert_array_equal(history.best_fitness, history.fitness.max(axis=1))
    assert file_kind(whole) == "task" and is_task_run(whole)
    with pytest.raises(RunFileError, match="is a task run"):  # a robot reader is told
        RunReader(whole)


def test_a_task_run_is_followed_while_it_is_written_and_holds_the_writer_lock(
    tmp_path: Path,
) -> None:
    seen: list[int] = []
    path = tmp_path / "live.h5"

    def look(_summary: object) -> None:  # a reader in the writer's process, as the dashboard's
        seen.append(read_task_run(path).generation_done)
        with pytest.raises(RunFileError, match="being written by another"):
            resume_task(path)

    train_task(_config(), path, look)
    assert seen == [1, 2, 3]


@pytest.mark.parametrize(
    ("env_steps", "layout_1"), [(True, False), (False, False), (True, True)], ids=str
)
def test_an_old_task_run_file_reads_lists_replays_and_exports_as_before(
    whole: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    env_steps: bool,
    layout_1: bool,
) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    old = write_old_task_run(whole, runs / "old.h5", env_steps=env_steps, layout_1=layout_1)
    new, read = read_task_run(whole), read_task_run(old)
    assert read.legacy and not new.legacy and is_task_run(old) and file_kind(old) == "task"
    assert read.config == new.config and read.generation_done == new.generation_done == 3
    for name in ("fitness", "epsilon", "alpha"):
        np.testing.assert_array_equal(getattr(read, name), getattr(new, name))
    if env_steps:
        np.testing.assert_array_equal(read.env_steps, new.env_steps)
    else:
        assert read.env_steps is None
    for g in range(3):
        for name, values in new.best_arrays(g).items():
            np.testing.assert_array_equal(read.best_arrays(g)[name], values)
    assert replay_task(old, 11) == replay_task(whole, 11)
    (summary,) = list_runs(runs)
    assert (
        summary.error is None and summary.task == "CartPole-v1" and summary.brain == DEFAULT_BRAIN
    )
    assert summary.finished and summary.best_fitness == new.fitness.max()
    assert main(["runs", "--runs-dir", str(runs)]) == 0
    assert "task CartPole-v1" in capsys.readouterr().out
    assert main(["runs", "old", "--runs-dir", str(runs)]) == 0
    assert capsys.readouterr().out.startswith("task run old.h5: CartPole-v1, seed 4")
    out = tmp_path / "export"
    assert main(["export", "old", "--runs-dir", str(runs), "--out", str(out)]) == 0
    document = json.loads((out / "controller.json").read_text())
    assert document["settings"]["fitness"] == new.fitness[-1].max()
    with pytest.raises(RunFileError, match="finished run"):
        resume_task(old)


@pytest.mark.parametrize("env_steps", [True, False], ids=["env-steps", "before-45"])
def test_an_old_cut_task_run_resumes_into_the_run_format_to_the_bit(
    whole: Path, tmp_path: Path, env_steps: bool
) -> None:
    cut = _cut(_config(), tmp_path / "new-cut.h5")
    old = write_old_task_run(cut, tmp_path / "old.h5", env_steps=env_steps)
    assert read_task_run(old).generation_done == 1
    resume_task(old)
    assert file_kind(old) == "task" and not read_task_run(old).legacy
    assert list(tmp_path.glob(".*")) == []  # no lock or temporary file left
    resumed, first = read_task_run(old), read_task_run(whole)
    np.testing.assert_array_equal(resumed.fitness, first.fitness)
    for name, values in first.best_arrays().items():
        np.testing.assert_array_equal(resumed.best_arrays()[name], values)
    if env_steps:
        np.testing.assert_array_equal(resumed.env_steps, first.env_steps)
    else:  # generation 0's are not known: the run's are not
        assert resumed.env_steps is None
        with RunReader(old, TASK) as run:
            steps = run.history().env_steps
        assert steps is not None and steps[0] == -1
        np.testing.assert_array_equal(steps[1:], np.asarray(first.env_steps)[1:])


def _damage(path: Path, change: str) -> None:
    with h5py.File(path, "r+", locking=False) as handle:
        if change == "deep config":
            handle.attrs["config"] = "[" * 100_000 + "]" * 100_000
        elif change == "a robot's config":
            handle.attrs["config"] = json.dumps({"seed": 4})
        elif change == "an unknown kind":
            handle.attrs["kind"] = "submarine"
        elif change == "fitness of the wrong shape":
            del handle["generations/fitness"]
            handle["generations/fitness"] = np.zeros((3, 2))
        elif change == "env-steps of strings":
            del handle["generations/env_steps"]
            handle["generations/env_steps"] = np.array([b"a", b"b", b"c"])
        elif change == "progress beyond the data":
            handle["progress/generations_done"][()] = 10**9
        else:
            raise AssertionError(change)


TASK_CHANGES = (
    "deep config",
    "a robot's config",
    "an unknown kind",
    "fitness of the wrong shape",
    "env-steps of strings",
    "progress beyond the data",
)


@pytest.mark.parametrize("change", TASK_CHANGES)
def test_a_damaged_task_run_is_one_line_everywhere(
    whole: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], change: str
) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    shutil.copy(whole, runs / "good.h5")
    bad = runs / "bad.h5"
    cut = _cut(_config(), bad)  # a resumable one, so that resume reads it
    _damage(cut, change)
    with pytest.raises(RunFileError):
        read_task_run(bad)
    summaries = {s.name: s for s in list_runs(runs)}
    assert summaries["bad"].error is not None and summaries["good"].error is None
    assert main(["runs", "--runs-dir", str(runs)]) == 0
    capsys.readouterr()
    commands = [
        ["runs", "bad", "--runs-dir", str(runs)],
        ["replay", "bad", "--runs-dir", str(runs)],
        ["export", "bad", "--runs-dir", str(runs), "--out", str(tmp_path / "export")],
    ]
    if change != "progress beyond the data":  # a resume goes on from the checkpoint
        commands.append(["train", "--resume", str(bad), "--quiet"])
    for argv in commands:
        assert main(argv) != 0, argv
        one_error_line(capsys, "bad.h5")


def test_a_task_run_on_a_full_disk_stops_cleanly_and_resumes_to_the_bit(
    whole: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from app.store import space

    path = tmp_path / "full.h5"

    def fill_the_disk(_summary: object) -> None:  # after generation 0 is done
        monkeypatch.setattr(space, "free_bytes", lambda _folder: 0)

    with pytest.raises(space.DiskFullError, match="no space left on the disk") as raised:
        train_task(_config(), path, fill_the_disk)
    assert f"gnp-lab train --resume {path}" in str(raised.value)
    assert read_task_run(path).generation_done == 1
    monkeypatch.undo()
    resume_task(path)
    np.testing.assert_array_equal(read_task_run(path).fitness, read_task_run(whole).fitness)
    assert list(tmp_path.glob(".*")) == []
