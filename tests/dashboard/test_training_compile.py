"""The dashboard's training says numba's first compile in its line: `TrainingJob.phase`, kernel
by kernel from the child process that compiles, then that it is done; then it trains."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from conftest import tiny_run_config

from app.dashboard import training_job
from app.dashboard.training_job import TrainingJob
from app.phases.warm import COMPILING


@pytest.mark.slow
def test_a_cold_cache_is_compiled_aside_and_said(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The child compiles into an empty cache of its own (this process's numba keeps its own).
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(training_job, "kernels_warm", lambda _configs: False)
    job = TrainingJob(tiny_run_config("CS"), tmp_path / "run.h5", workers=1)
    said: list[str] = []
    while job.active:
        if job.phase and (not said or said[-1] != job.phase):
            said.append(job.phase)
        time.sleep(0.02)
    assert job.state == "finished", job.error()
    assert said[0].startswith(COMPILING)
    assert any(line.startswith("compiled gnp.kernel.step_kernel") for line in said)
    assert said[-1].startswith("kernels compiled: ")
    assert not job.compiling
