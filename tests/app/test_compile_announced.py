"""numba's first compile is said ("compiling kernels, first run only", each kernel, done) by
`gnp-lab` and by the warm-up the dashboard runs; on a warm cache nothing is said. Each test
points numba at a cache of its own (NUMBA_CACHE_DIR), empty at first, in fresh interpreters."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from app.phases.warm import COMPILING

ROOT = Path(__file__).resolve().parents[2]
ENTRY = "import sys; from app.cli import main; sys.exit(main())"  # the gnp-lab script
TINY = ["--preset", "quick", "--population", "4", "--generations", "1", "--steps", "5"]
WARM_CHECK = (
    "from app.phases.warm import kernels_warm; from app.settings.loading import build_config; "
    "from app.settings.config import preset_layer; "
    "print(kernels_warm([build_config(preset_layer('quick'))]))"
)


def python(cache: Path, *arguments: str, timeout: float = 900) -> subprocess.CompletedProcess:
    """A fresh interpreter on numba cache `cache`."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    return subprocess.run(
        [sys.executable, *arguments],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def test_a_cold_cache_is_announced_and_a_warm_one_says_nothing(tmp_path: Path) -> None:
    """`train --print-config` imports the simulator, whose modules compile small kernels at
    import (`sim.kernel_cache.drop_stale_cache`): the smallest cold start of the CLI."""
    cold = python(tmp_path, "-c", ENTRY, "train", "--print-config")
    assert cold.returncode == 0, cold.stderr
    lines = cold.stderr.splitlines()
    assert lines[0].startswith(f"gnp-lab: {COMPILING}")
    assert any(line.startswith("gnp-lab:   compiled sim.") for line in lines[1:-1])
    assert lines[-1].startswith("gnp-lab: kernels compiled: ")
    warm = python(tmp_path, "-c", ENTRY, "train", "--print-config")
    assert warm.returncode == 0 and warm.stderr == ""
    assert warm.stdout == cold.stdout


def test_kernels_warm_gives_up_at_the_first_compile(tmp_path: Path) -> None:
    python(tmp_path, "-c", "import app.phases.warm")  # the import's own small kernels
    done = python(tmp_path, "-c", WARM_CHECK)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


@pytest.mark.slow
def test_train_says_it_compiles_first_then_trains(tmp_path: Path) -> None:
    """The run's kernels are compiled by its warm-up, said kernel by kernel before the progress
    bar; then the cache is warm for the dashboard's check and for the next run, which says
    nothing of it."""
    cache = tmp_path / "cache"
    argv = ["-c", ENTRY, "train", *TINY, "--workers", "1"]
    cold = python(cache, *argv, "--out", str(tmp_path / "a.h5"))
    assert cold.returncode == 0, cold.stderr
    lines = cold.stderr.splitlines()
    assert lines[0].startswith(f"gnp-lab: {COMPILING}")
    done = next(i for i, line in enumerate(lines) if line.startswith("gnp-lab: kernels compiled"))
    assert "gnp-lab:   compiled gnp.kernel.step_kernel" in "\n".join(lines[:done])
    assert all(line.startswith("gnp-lab:") for line in lines[: done + 1])  # before the bar
    assert python(cache, "-c", WARM_CHECK).stdout.strip() == "True"
    warm = python(cache, *argv, "--out", str(tmp_path / "b.h5"))
    assert warm.returncode == 0, warm.stderr
    assert "gnp-lab:" not in warm.stderr
