"""File safety: a file is replaced whole or not at all, by every path that rewrites one."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from lab_fixtures import file_digest, tiny_config
from test_store_schema import an_implementation

import gnp
from app.brains.gnp_brain import initial_population
from app.brains.registry import family_of
from app.store import (
    Implementation,
    RunFileError,
    RunReader,
    RunWriter,
    add_implementation,
    writer,
)
from app.store.files import atomic_file


class Crash(Exception):
    """Stands for anything that stops a rewrite half-way (an error, a full disk, a signal)."""


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_a_failure_half_way_leaves_the_original_intact(tmp_path: Path) -> None:
    path = tmp_path / "file.bin"
    path.write_bytes(b"original")
    with pytest.raises(Crash), atomic_file(path, overwrite=True) as tmp:
        tmp.write_bytes(b"half of the new")
        raise Crash
    assert path.read_bytes() == b"original"
    assert _leftovers(tmp_path) == []


def test_a_finished_block_replaces_the_file(tmp_path: Path) -> None:
    path = tmp_path / "file.bin"
    path.write_bytes(b"original")
    with atomic_file(path, overwrite=True) as tmp:
        assert tmp.parent == path.parent and tmp != path
        tmp.write_bytes(b"new")
        assert path.read_bytes() == b"original"  # nothing shows before the block ends
    assert path.read_bytes() == b"new"
    assert _leftovers(tmp_path) == []


def test_without_overwrite_an_existing_file_is_kept(tmp_path: Path) -> None:
    path = tmp_path / "file.bin"
    path.write_bytes(b"original")
    with pytest.raises(FileExistsError), atomic_file(path, overwrite=False) as tmp:
        tmp.write_bytes(b"new")
    assert path.read_bytes() == b"original"
    assert _leftovers(tmp_path) == []


def test_an_implementation_that_fails_half_way_leaves_the_run_intact(
    tmp_path: Path, finished_run: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "run.h5"
    shutil.copy(finished_run, path)
    before = file_digest(path)
    store_implementation = writer._store_implementation

    def half(handle: h5py.File, result: Implementation) -> None:
        store_implementation(handle, result)
        raise Crash

    monkeypatch.setattr(writer, "_store_implementation", half)
    with pytest.raises(Crash):
        add_implementation(path, an_implementation())
    assert file_digest(path) == before
    assert _leftovers(tmp_path) == []
    monkeypatch.undo()
    add_implementation(path, an_implementation())  # and the lock was released
    with RunReader(path) as run:
        assert run.implementation_names() == ["probe"]


def test_a_resume_that_fails_half_way_leaves_the_run_intact(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    config = tiny_config()
    path = tmp_path / "run.h5"
    with RunWriter.create(path, family_of(config).run_template()) as run:
        run.write_checkpoint(1, gnp.population_to_arrays(initial_population(config)))
    before = file_digest(path)

    def crash(_source: h5py.File, target: h5py.File) -> None:
        target["generations/fitness"][0] = np.arange(12)  # some of the copy, then the crash
        raise Crash

    monkeypatch.setattr(writer, "_copy_values", crash)
    with pytest.raises(Crash):
        RunWriter.resume(path)
    assert file_digest(path) == before
    assert _leftovers(tmp_path) == []
    monkeypatch.undo()
    resumed, generation, _ = RunWriter.resume(path)
    resumed.close()
    assert generation == 1


def test_a_create_that_fails_half_way_leaves_no_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "run.h5"

    def crash(handle: h5py.File, _template: object) -> None:
        handle.create_group("progress")
        raise Crash

    monkeypatch.setattr(writer, "build_run_layout", crash)
    with pytest.raises(Crash):
        RunWriter.create(path, family_of(tiny_config()).run_template())
    assert not path.exists()
    assert _leftovers(tmp_path) == []
    monkeypatch.undo()
    RunWriter.create(path, family_of(tiny_config()).run_template()).close()  # the lock was released
    with pytest.raises(RunFileError, match="already exists"):
        RunWriter.create(path, family_of(tiny_config()).run_template())
