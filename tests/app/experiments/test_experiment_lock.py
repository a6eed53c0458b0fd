"""The experiment lock (filelock's, `app.experiments.lock`): one holder, its pid in the file,
no file left, and the same messages as before."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from app.experiments.lock import LOCK_NAME, experiment_lock, holder_elsewhere
from app.experiments.spec import ExperimentError
from app.store.files import release_lock, take_lock, writer_lock_path


def test_the_holder_writes_its_pid_and_leaves_no_file(tmp_path: Path) -> None:
    folder = tmp_path / "runs" / "tiny"  # created
    with experiment_lock(folder):
        assert (folder / LOCK_NAME).read_text(encoding="utf-8") == f"{os.getpid()}\n"
    assert not (folder / LOCK_NAME).exists()
    with experiment_lock(folder):  # and it can be taken again
        pass
    assert list(folder.iterdir()) == []


def test_a_second_holder_is_refused_with_the_first_ones_pid(tmp_path: Path) -> None:
    with (
        experiment_lock(tmp_path),
        pytest.raises(ExperimentError) as refused,
        experiment_lock(tmp_path),
    ):
        pass
    assert str(refused.value) == (
        f"experiment {tmp_path.name!r} is already running (pid {os.getpid()}); wait for it "
        "to finish or stop it, then run the same command to go on"
    )


def test_another_process_is_refused_and_a_killed_holder_frees_it(tmp_path: Path) -> None:
    script = (
        "import time; from app.experiments.lock import experiment_lock\n"
        f"with experiment_lock({str(tmp_path)!r}):\n"
        "    print('held', flush=True); time.sleep(60)"
    )
    holder = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n"
        refused = rf"already running \(pid {holder.pid}\)"
        with pytest.raises(ExperimentError, match=refused), experiment_lock(tmp_path):
            pass
    finally:
        holder.kill()
        holder.wait()
    with experiment_lock(tmp_path):  # the kernel dropped the killed holder's lock
        assert (tmp_path / LOCK_NAME).read_text(encoding="utf-8") == f"{os.getpid()}\n"


def test_temporaries_of_killed_runs_are_cleared(tmp_path: Path) -> None:
    scale = tmp_path / "smoke"
    scale.mkdir()
    left = scale / ".run-0.h5.999999999.tmp"  # a pid that runs nowhere
    left.write_bytes(b"")
    with experiment_lock(tmp_path):
        assert not left.exists()


def test_a_complete_runs_lock_left_by_a_killed_writer_is_cleared(tmp_path: Path) -> None:
    """Seen in a test that kills an experiment at ten moments: one killed after its run was
    complete, before it removed the run's lock file; no resume writes that run again, so the
    file stayed. A lock a live writer holds stays."""
    scale = tmp_path / "smoke"
    scale.mkdir()
    stale, held = scale / "RL-seed0.h5", scale / "RL-seed1.h5"
    for run in (stale, held):
        run.write_bytes(b"")
        writer_lock_path(run).write_text("")
    holder = take_lock(writer_lock_path(held))  # another open file: flock conflicts with it
    assert holder is not None
    try:
        with experiment_lock(tmp_path):
            assert not writer_lock_path(stale).exists()
            assert writer_lock_path(held).exists()
    finally:
        release_lock(writer_lock_path(held), holder)
    assert sorted(p.name for p in scale.iterdir()) == ["RL-seed0.h5", "RL-seed1.h5"]


def test_a_folder_that_cannot_be_made_is_refused(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("")
    with (
        pytest.raises(ExperimentError, match="cannot write in"),
        experiment_lock(tmp_path / "file" / "tiny"),
    ):
        pass


def test_the_holder_writes_the_scale_it_runs_and_others_read_it(tmp_path: Path) -> None:
    """What the dashboard reads of a run in another process: its pid and scale, never this
    process's own, nor a killed holder's (its file stays, its pid runs nowhere)."""
    with experiment_lock(tmp_path, "small"):
        assert (tmp_path / LOCK_NAME).read_text(encoding="utf-8") == f"{os.getpid()}\nsmall\n"
        assert holder_elsewhere(tmp_path) is None  # ours
    assert holder_elsewhere(tmp_path) is None  # nobody
    (tmp_path / LOCK_NAME).write_text("999999999\nsmall\n")  # a pid that runs nowhere
    assert holder_elsewhere(tmp_path) is None
    (tmp_path / LOCK_NAME).write_text(f"{os.getppid()}\nthesis\n")  # a live process
    assert holder_elsewhere(tmp_path) == (os.getppid(), "thesis")
    (tmp_path / LOCK_NAME).write_text("")  # a holder that has not written yet
    assert holder_elsewhere(tmp_path) is None
    (tmp_path / LOCK_NAME).write_bytes(b"\xff\xfe junk")  # not one a holder wrote
    assert holder_elsewhere(tmp_path) is None
