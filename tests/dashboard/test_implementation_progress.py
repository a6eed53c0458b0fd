"""The Runs tab's implementation phase in its child process: its progress reaches the total, a
cancel ends the child within seconds and writes nothing, and its results are bit for bit those
of `gnp-lab implement` (`app.phases.implementation.implement`) for the same settings."""

from __future__ import annotations

import hashlib
import itertools
import shutil
import time
from pathlib import Path

import numpy as np
import psutil
import pytest
from page_helpers import until

from app.dashboard.implementation_job import (
    ImplementationJob,
    ImplementationRequest,
    implement_run,
    trial_steps,
)
from app.phases.implementation import implement
from app.store import Implementation, RunReader


def request_of(
    run: Path, steps: int, repeats: int, noise: float | None = 30.0
) -> ImplementationRequest:
    return ImplementationRequest(run, (2, 3), "dead", 100, steps, repeats, "fixed", noise)


def job_of(request: ImplementationRequest) -> ImplementationJob:
    with RunReader(request.run) as run:
        settings = request.settings(run.config.implementation)
    return ImplementationJob(request, trial_steps(settings))


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def assert_same(a: Implementation, b: Implementation) -> None:
    for field in ("reward_per_step", "trial_mean_reward", "trial_mean_after_fault", "start_index"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert (a.mean_reward, a.mean_after_fault, a.generation) == (
        b.mean_reward,
        b.mean_after_fault,
        b.generation,
    )
    assert a.settings == b.settings


def test_progress_reaches_the_total_and_the_results_are_the_clis(
    runs_dir: Path, tmp_path: Path
) -> None:
    request = request_of(runs_dir / "bs.h5", steps=300, repeats=2)
    before = digest(request.run)
    job = job_of(request)
    assert job.total == 10 * 2 * 300  # 10 start poses × 2 repeats, 300 steps each
    seen = []

    def finished() -> bool:
        seen.append(job.progress())
        return not job.active

    until(finished, 300)
    done = job.progress()
    assert (done.state, done.done, done.total, done.fraction) == ("finished", 6000, 6000, 1.0)
    assert all(a.done <= b.done for a, b in itertools.pairwise(seen))  # never back
    assert "finished · 20 of 20 trials · 100%" in done.describe()
    result = job.result()
    assert digest(request.run) == before  # nothing written to the run
    # The CLI's function on a copy of the run, with the same settings: the same bits.
    copy = tmp_path / "copy.h5"
    shutil.copy(request.run, copy)
    assert_same(result, implement(copy, result.settings, name="cli"))
    assert_same(result, implement_run(request))  # and in this process, without the child
    assert result.settings.noise_sigma == 30.0


def test_the_runs_own_noise_is_used_when_none_is_given(runs_dir: Path) -> None:
    request = request_of(runs_dir / "cs.h5", steps=120, repeats=1, noise=None)
    with RunReader(request.run) as run:
        own = run.config.implementation.noise_sigma
    assert implement_run(request).settings.noise_sigma == own


def test_cancel_ends_the_child_within_seconds_and_writes_nothing(runs_dir: Path) -> None:
    request = request_of(runs_dir / "cs.h5", steps=3000, repeats=300)  # minutes of work
    before = digest(request.run)
    others = set(psutil.Process().children())  # e.g. another test's browser in this worker
    job = job_of(request)
    children = [c for c in psutil.Process().children() if c not in others]
    assert children, "the job runs in a child process"
    until(lambda: job.progress().done > 0, 300)  # under way, and saying so
    assert job.progress().state == "running"
    start = time.monotonic()
    job.cancel()
    _gone, alive = psutil.wait_procs(children, timeout=5)
    assert not alive, "the child outlived its cancel"
    assert time.monotonic() - start < 5
    progress = job.progress()
    assert progress.state == "cancelled" and not job.active
    assert 0 < progress.done < progress.total
    with pytest.raises(RuntimeError, match="cancelled"):
        job.result()
    assert digest(request.run) == before
