"""The page's lists of runs follow the runs dir (`app.dashboard.runs_watch.RunsWatch`): a run
added, removed or being written (by `gnp-lab` in another terminal) shows in the Runs tab's table
and lists without *Refresh list*; only the files that changed are read again, and a file caught
half-way through a write keeps its earlier line until it can be read."""

from __future__ import annotations

import os
import shutil
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from page_helpers import DEMO, dashboard_in_process, until
from test_task_replay import tiny_task_config

from app import store
from app.dashboard.runs_watch import TORN_SECONDS, RunsWatch
from app.phases.generations import GenerationSummary
from app.store import catalogue
from app.store.files import SETTLED_SECONDS
from app.tasks import train_task


@pytest.fixture(scope="module")
def task_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("watched") / "cartpole.h5"
    train_task(tiny_task_config(), path)
    return path


@pytest.fixture
def reads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The names of the run files `store.summarize` reads, in order (also through
    `store.list_runs`)."""
    read: list[str] = []
    summarize = store.summarize

    def counted(path: Path) -> store.RunSummary:
        read.append(path.stem)
        return summarize(path)

    monkeypatch.setattr(store, "summarize", counted)
    monkeypatch.setattr(catalogue, "summarize", counted)  # `store.list_runs`' own
    return read


def aged(path: Path, seconds: float = 2 * TORN_SECONDS) -> None:
    """Date `path`'s last write `seconds` back."""
    then = time.time() - seconds
    os.utime(path, (then, then))


def lines(runs: list[store.RunSummary] | None) -> dict[str, str]:
    """name → what the table says of it ("3/3" done, or its error)."""
    assert runs is not None, "the look saw no change"
    return {r.name: r.error or f"{r.generations_done}/{r.generations}" for r in runs}


def test_a_look_reads_only_what_changed(tmp_path: Path, task_run: Path, reads: list[str]) -> None:
    watch = RunsWatch(tmp_path / "missing")
    assert watch.look() is None  # no runs dir, no runs: nothing changed from nothing
    watch = RunsWatch(tmp_path)
    shutil.copyfile(task_run, tmp_path / "a.h5")
    aged(tmp_path / "a.h5")  # settled: see the next test
    assert lines(watch.look()) == {"a": "3/3"}
    assert watch.look() is None and reads == ["a"]
    shutil.copyfile(task_run, tmp_path / "b.h5")
    aged(tmp_path / "b.h5")
    assert lines(watch.look()) == {"a": "3/3", "b": "3/3"}
    assert reads == ["a", "b"]
    aged(tmp_path / "a.h5", 3 * TORN_SECONDS)  # rewritten: a new modification time
    assert lines(watch.look()) == {"a": "3/3", "b": "3/3"}
    assert reads == ["a", "b", "a"]
    (tmp_path / "b.h5").unlink()
    assert lines(watch.look()) == {"a": "3/3"} and reads == ["a", "b", "a"]
    assert lines(watch.look(again=True)) == {"a": "3/3"}  # Refresh list: everything, again
    assert reads == ["a", "b", "a", "a"]


def test_a_file_written_lately_is_read_at_each_look_until_it_settles(
    tmp_path: Path, task_run: Path, reads: list[str]
) -> None:
    """Two writes in one tick of the file system's clock leave the same stamp: until a file
    settles, an unchanged stamp does not tell that it is unchanged."""
    shutil.copyfile(task_run, tmp_path / "a.h5")
    watch = RunsWatch(tmp_path)
    assert lines(watch.look()) == {"a": "3/3"}
    assert lines(watch.look()) == {"a": "3/3"}
    assert reads == ["a", "a"]
    aged(tmp_path / "a.h5", SETTLED_SECONDS + 1)
    assert lines(watch.look()) == {"a": "3/3"}
    assert watch.look() is None and reads == ["a"] * 3


def test_a_torn_read_keeps_the_earlier_line_until_the_write_is_old(
    tmp_path: Path, task_run: Path, reads: list[str]
) -> None:
    run = tmp_path / "run.h5"
    shutil.copyfile(task_run, run)
    watch = RunsWatch(tmp_path)
    assert lines(watch.look()) == {"run": "3/3"}
    run.write_bytes(b"half of an HDF5 file")  # caught mid-write
    assert lines(watch.look()) == {"run": "3/3"}
    assert lines(watch.look()) == {"run": "3/3"}  # read again at each look meanwhile
    assert reads == ["run"] * 3
    aged(run)  # nobody wrote it for long: the file is what it is
    assert lines(watch.look())["run"].startswith("not an HDF5 file")
    assert watch.look() is None and reads == ["run"] * 4


def test_a_new_unreadable_file_shows_its_error_at_once(tmp_path: Path) -> None:
    (tmp_path / "junk.h5").write_text("not a run")
    watch = RunsWatch(tmp_path)
    assert lines(watch.look())["junk"].startswith("not an HDF5 file")
    aged(tmp_path / "junk.h5")
    assert lines(watch.look())["junk"].startswith("not an HDF5 file")  # read again, settled
    assert watch.look() is None


@pytest.fixture
def board(tmp_path: Path) -> Iterator[Any]:
    with dashboard_in_process(tmp_path) as dashboard:
        yield dashboard


def test_the_page_follows_runs_written_added_and_removed(board: Any, tmp_path: Path) -> None:
    """A run written in another thread (as by `gnp-lab train` in another terminal) shows its
    generations as they come, in the table and the Run list, with no click; a robot run copied
    in joins the Compare tab's lists; a run removed leaves them."""
    assert "No runs in" in board.runs.table.content
    release, written = threading.Event(), threading.Event()

    def hold(summary: GenerationSummary) -> None:
        if summary.generation == 0:
            written.set()
            assert release.wait(60)

    writer = threading.Thread(
        target=train_task, args=(tiny_task_config(seed=2), tmp_path / "growing.h5", hold)
    )
    writer.start()
    try:
        assert written.wait(60)
        until(lambda: "| growing | task CartPole-v1 | 1/3 … |" in board.runs.table.content, 30)
        assert "growing" in board.runs.run.options
    finally:
        release.set()
        writer.join(60)
    until(lambda: "| growing | task CartPole-v1 | 3/3 |" in board.runs.table.content, 30)
    assert "growing" not in board.compare.run_a.options  # a task run: not the robot's to compare
    shutil.copyfile(DEMO, tmp_path / "demo.h5")
    until(lambda: "demo" in board.compare.run_a.options and "demo" in board.runs.run.options, 30)
    (tmp_path / "growing.h5").unlink()
    until(lambda: "growing" not in board.runs.table.content, 30)
    assert board.runs.run.options == ("demo",)


def test_the_page_reads_each_run_once_as_it_opens(
    tmp_path: Path, task_run: Path, reads: list[str]
) -> None:
    """The runs dir is read once to list the runs and to choose the run shown first."""
    shutil.copyfile(DEMO, tmp_path / "demo.h5")
    shutil.copyfile(task_run, tmp_path / "cartpole.h5")
    for run in ("demo", "cartpole"):
        aged(tmp_path / f"{run}.h5")  # settled: the page's loop does not read them again
    with dashboard_in_process(tmp_path) as board:
        assert sorted(reads) == ["cartpole", "demo"]
        assert board.runs.loaded_name == "demo"
        assert "| cartpole | task CartPole-v1 | 3/3 |" in board.runs.table.content
