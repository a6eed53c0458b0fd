"""`planning.StateCache`: a run file's state (`inspect`) is read again only when the file
changed, or while it may still be being written; a refusal is remembered as one; what it hands
back is the caller's to change."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from experiment_fixtures import write_tiny

from app.experiments import planning
from app.experiments.planning import RunState, StateCache, Task
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import load_file
from app.store.files import SETTLED_SECONDS


def aged(path: Path, seconds: float = 60.0) -> None:
    then = time.time() - seconds
    os.utime(path, (then, then))


def task_at(path: Path) -> Task:
    return Task("RL", 0, str(path), "{}", (), 1, 1)


@pytest.fixture
def reads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """`planning.inspect` stood in for: the run's generations done are the file's size (no
    file: none done, as `inspect` says)."""
    read: list[str] = []

    def inspect(task: Task) -> RunState:
        read.append(Path(task.path).name)
        if not Path(task.path).exists():
            return RunState(generations=100)
        size = Path(task.path).stat().st_size
        return RunState(generations_done=size, generations=100, finished=size == 100)

    monkeypatch.setattr(planning, "inspect", inspect)
    return read


def test_an_unchanged_file_is_read_once_and_a_changed_one_again(
    tmp_path: Path, reads: list[str]
) -> None:
    run = tmp_path / "RL-seed0.h5"
    run.write_bytes(b"x" * 40)
    aged(run)
    cache, task = StateCache(), task_at(run)
    assert cache.inspect(task).generations_done == 40
    assert cache.inspect(task).generations_done == 40
    assert reads == ["RL-seed0.h5"]
    run.write_bytes(b"x" * 100)  # written on: a new size and times
    aged(run)
    state = cache.inspect(task)
    assert (state.generations_done, state.finished) == (100, True)
    assert reads == ["RL-seed0.h5"] * 2


def test_a_file_written_lately_is_read_each_time(tmp_path: Path, reads: list[str]) -> None:
    """Two writes in one tick of the file system's clock leave the same times: a file still
    being written is never remembered."""
    run = tmp_path / "RL-seed0.h5"
    run.write_bytes(b"x" * 40)
    cache, task = StateCache(), task_at(run)
    cache.inspect(task)
    cache.inspect(task)
    assert reads == ["RL-seed0.h5"] * 2
    aged(run, SETTLED_SECONDS + 1)
    cache.inspect(task)
    cache.inspect(task)
    assert reads == ["RL-seed0.h5"] * 3


def test_a_missing_file_is_an_empty_state_and_nothing_is_kept(
    tmp_path: Path, reads: list[str]
) -> None:
    cache, task = StateCache(), task_at(tmp_path / "absent.h5")
    assert cache.inspect(task) == RunState(generations=100)
    (tmp_path / "absent.h5").write_bytes(b"x" * 7)
    aged(tmp_path / "absent.h5")
    assert cache.inspect(task).generations_done == 7  # appeared: read
    assert reads == ["absent.h5", "absent.h5"]


def test_the_state_handed_back_is_a_copy(tmp_path: Path, reads: list[str]) -> None:
    run = tmp_path / "RL-seed0.h5"
    run.write_bytes(b"x" * 40)
    aged(run)
    cache, task = StateCache(), task_at(run)
    cache.inspect(task).generations_done = 0
    assert cache.inspect(task).generations_done == 40
    assert reads == ["RL-seed0.h5"]


def test_a_foreign_file_is_refused_each_time_read_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The real `inspect` on a file that is no run of the experiment's: the same refusal every
    time, from one read."""
    spec = load_file(write_tiny(tmp_path))
    task = planning.plan(spec, "smoke", tmp_path / "runs")[0]
    Path(task.path).parent.mkdir(parents=True)
    Path(task.path).write_text("not a run file")
    aged(Path(task.path))
    with pytest.raises(ExperimentError) as fresh:
        planning.inspect(task)
    cache = StateCache()
    with pytest.raises(ExperimentError) as first:
        cache.inspect(task)
    read = planning.inspect

    def never(task: Task) -> RunState:
        raise AssertionError(f"{task.name} read again")

    monkeypatch.setattr(planning, "inspect", never)
    with pytest.raises(ExperimentError) as again:
        cache.inspect(task)
    assert str(fresh.value) == str(first.value) == str(again.value)
    monkeypatch.setattr(planning, "inspect", read)  # the other runs' files: absent, read
    status = planning.scale_status(spec, "smoke", tmp_path / "runs", read=cache.inspect)
    assert status.problems == {task.key: str(fresh.value)} and status.done == 0
