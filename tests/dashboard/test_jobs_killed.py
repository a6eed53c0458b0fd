"""The dashboard's jobs when its process is killed: the workers of a training job (started from
the job's thread) and of an implementation job (started from a thread that has ended since, as
a page's callback thread may) end within 3 s of a `kill -9` of the dashboard, and the run
resumes."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
from pathlib import Path

import psutil
import pytest
from lab_fixtures import (
    children_of,
    finish,
    generations_done,
    gnp_lab,
    kill_alone,
    python,
    tiny_config,
    wait_for,
)

from app.store import RunReader

TRAINING_JOB = """
import sys, time
from pathlib import Path
from app.settings.config import RunConfig
from app.dashboard.training_job import TrainingJob

config = RunConfig.model_validate_json(Path(sys.argv[1]).read_text())
job = TrainingJob(config, Path(sys.argv[2]), workers=2)
while job.active:
    time.sleep(0.1)
"""

IMPLEMENTATION_JOB = """
import sys, threading, time
from pathlib import Path
from app.dashboard.implementation_job import ImplementationJob, ImplementationRequest

request = ImplementationRequest(run=Path(sys.argv[1]), sensors=(2, 3), mode="dead",
                                fault_step=500, steps=3000, repeats=200, schedule="fixed")
jobs = []
starter = threading.Thread(target=lambda: jobs.append(ImplementationJob(request)))
starter.start()
starter.join()  # the thread that started the worker has ended
while jobs[0].active:
    time.sleep(0.1)
"""


def _busiest_child_cpu(process: subprocess.Popen[bytes]) -> float:
    """The most CPU seconds any descendant of `process` has used so far."""
    used = [0.0]
    for child in psutil.Process(process.pid).children(recursive=True):
        with contextlib.suppress(psutil.NoSuchProcess):
            used.append(sum(child.cpu_times()[:2]))
    return max(used)


@pytest.mark.slow
def test_a_killed_dashboards_training_job_leaves_no_worker_and_resumes(tmp_path: Path) -> None:
    config = tmp_path / "config.json"
    config.write_text(tiny_config(population=16, steps=1000, generations=24, shard_size=8)
                      .model_dump_json())  # fmt: skip
    out = tmp_path / "run.h5"
    process = python("-c", TRAINING_JOB, config, out)
    wait_for(lambda: process.poll() is not None or generations_done(out) >= 1)
    os.kill(process.pid, signal.SIGSTOP)  # frozen: it cannot finish before it is looked at
    assert process.poll() is None, finish(process)
    assert children_of(process) >= 2
    assert kill_alone(process) == []
    status, err = finish(gnp_lab("train", "--resume", out, "--workers", "1", "--quiet"))
    assert status == 0, err
    with RunReader(out) as run:
        assert run.finished


@pytest.mark.slow
def test_a_killed_dashboards_implementation_job_leaves_no_worker(
    tmp_path: Path, runs_dir: Path
) -> None:
    run = tmp_path / "run.h5"
    shutil.copy(runs_dir / "bs.h5", run)
    process = python("-c", IMPLEMENTATION_JOB, run)
    # Until it is at its trials: a spawned worker watches its parent only once it has imported
    # what its job needs (about 0.7 CPU s; tens of wall seconds on a loaded machine).
    wait_for(lambda: process.poll() is not None or _busiest_child_cpu(process) >= 1.5)
    assert process.poll() is None, finish(process)
    assert kill_alone(process) == []
