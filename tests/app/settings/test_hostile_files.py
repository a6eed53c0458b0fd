"""Hostile files, impossible sizes and special files end on one line (issue #47).

Each kind of input the issue lists is given to `gnp-lab` as a user would (a subprocess, with a
timeout: a hang fails), and must end in one `gnp-lab: error:` line and a non-zero exit, or a
listing that marks the bad file and goes on; never a traceback. Kinds no command reads (a
controller file) are given to their reader.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from app.brains.registry import load_controller
from app.settings.user_files import JSON_MAX_DEPTH
from app.store.controller_file import ControllerFileError
from app.system.memory import available_memory

TIMEOUT = 120
ROOT = Path(__file__).resolve().parents[3]
DEEP = "[" * 100_000 + "]" * 100_000


def gnp_lab(*words: str | Path, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """`gnp-lab WORDS` in a subprocess (a hang fails the test through the timeout)."""
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *map(str, words)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        cwd=cwd or ROOT,
        check=False,
    )


def one_line(done: subprocess.CompletedProcess[str], *needles: str) -> str:
    """The command failed on one `gnp-lab: error:` line holding every needle."""
    assert done.returncode != 0, done.stdout
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    lines = [line for line in lines if not line.startswith("gnp-lab: compil")]  # numba's
    assert len(lines) == 1 and lines[0].startswith("gnp-lab: error: "), done.stderr
    assert "Traceback" not in done.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


@pytest.fixture
def runs(tmp_path: Path, finished_run: Path) -> Path:
    """A runs folder holding a copy of the finished tiny run as `good.h5`."""
    folder = tmp_path / "runs"
    folder.mkdir()
    shutil.copy(finished_run, folder / "good.h5")
    return folder


def _hostile(runs: Path, name: str, change: str) -> Path:
    """A copy of good.h5 as NAME.h5 with one change."""
    path = runs / f"{name}.h5"
    shutil.copy(runs / "good.h5", path)
    with h5py.File(path, "r+", locking=False) as handle:
        if change == "deep config":
            handle.attrs["config"] = DEEP
        elif change == "fitness of strings":
            del handle["generations/best_fitness"]
            handle["generations/best_fitness"] = np.array([b"a", b"b", b"c"])
        elif change == "fitness of the wrong shape":
            del handle["generations/best_fitness"]
            handle["generations/best_fitness"] = np.zeros((3, 2))
        elif change == "negative progress":
            handle["progress/generations_done"][()] = -6
        elif change == "progress beyond the data":
            handle["progress/generations_done"][()] = 10**9
        else:
            raise AssertionError(change)
    return path


RUN_CHANGES = (
    "deep config",
    "fitness of strings",
    "fitness of the wrong shape",
    "negative progress",
    "progress beyond the data",
)


@pytest.mark.parametrize("change", RUN_CHANGES)
def test_a_hostile_run_file_is_one_line_everywhere(runs: Path, change: str) -> None:
    _hostile(runs, "bad", change)
    listing = gnp_lab("runs", "--runs-dir", runs)
    assert listing.returncode == 0 and "Traceback" not in listing.stderr, listing.stderr
    rows = {line.split()[0]: line for line in listing.stdout.splitlines()[1:]}
    assert "unreadable" in rows["bad"] and "unreadable" not in rows["good"], listing.stdout
    one_line(gnp_lab("runs", "bad", "--runs-dir", runs), "bad.h5")
    out = runs.parent / "export"
    one_line(gnp_lab("export", "bad", "--runs-dir", runs, "--out", out), "bad.h5")
    implement = ("implement", "bad", "--runs-dir", runs, "--steps", "20", "--fault-step", "10")
    one_line(gnp_lab(*implement, "--workers", "1"), "bad.h5")


def test_a_fifo_is_refused_wherever_a_path_is_read(tmp_path: Path, runs: Path) -> None:
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    one_line(gnp_lab("train", "--config", fifo, "--print-config"), "regular file")
    one_line(
        gnp_lab("train", "--set", f"training.arena={json.dumps(str(fifo))}", "--print-config"),
        "regular file",
    )
    one_line(gnp_lab("experiment", "run", "--file", fifo, "--runs-dir", runs), "regular file")
    one_line(gnp_lab("train", "--resume", fifo), "regular file")
    os.mkfifo(runs / "pipe.h5")
    listing = gnp_lab("runs", "--runs-dir", runs)
    assert listing.returncode == 0 and "regular file" in listing.stdout, listing.stdout


def test_an_option_nested_too_deep_is_one_line() -> None:
    done = gnp_lab("train", "--set", f"training.steps={DEEP[:20000]}", "--print-config")
    one_line(done, "nested too deep")


def test_a_config_section_given_a_value_is_refused(tmp_path: Path) -> None:
    config = tmp_path / "five.toml"
    config.write_text("seed = 1\ntraining = 5\n")
    done = gnp_lab("train", "--config", config, "--population", "10", "--print-config")
    one_line(done, "training", "got 5")


def test_a_deep_or_huge_arena_is_one_line(tmp_path: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text(DEEP)
    one_line(gnp_lab("train", "--set", f'training.arena="{deep}"', "--print-config"), "deep")
    arena = json.loads((ROOT / "sim" / "arenas" / "training.json").read_text())
    arena["outer_wall"][1] = [1e300, arena["outer_wall"][1][1]]
    far = tmp_path / "far.json"
    far.write_text(json.dumps(arena))
    done = gnp_lab("train", "--set", f'training.arena="{far}"', "--print-config")
    line = one_line(done, "far.json")
    assert "np.float64" not in line and "Warning" not in done.stderr


@pytest.mark.skipif(
    (available_memory() or 0) > 50 * 2**30, reason="this machine could hold the population"
)
def test_an_impossible_population_is_refused_with_its_size(tmp_path: Path) -> None:
    words = ("--population", "100000", "--n-judgment", "400", "--n-processing", "200")
    done = gnp_lab("train", *words, "--n-sub", "8", "--out", tmp_path / "big.h5")
    one_line(done, "GiB of memory", "available")
    assert not (tmp_path / "big.h5").exists()


@pytest.fixture(scope="module")
def task_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("task-runs")
    done = gnp_lab(
        "train", "--task", "CartPole-v1", "--population", "6", "--generations", "1",
        "--steps", "20", "--out", folder / "cart.h5", "--quiet",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    return folder


def test_replay_refuses_a_negative_seed_and_impossible_episodes(task_runs: Path) -> None:
    one_line(gnp_lab("replay", "cart", "--runs-dir", task_runs, "--seed", "-1"), "--seed")
    done = gnp_lab("replay", "cart", "--runs-dir", task_runs, "--episodes", "100000000")
    one_line(done, "of memory", "available")


def test_a_module_task_id_is_refused(tmp_path: Path) -> None:
    task = "gymnasium.envs.classic_control:CartPole-v1"
    done = gnp_lab("train", "--task", task, "--population", "6", "--out", tmp_path / "t.h5")
    one_line(done, "module:id")


def test_a_hostile_controller_file_is_its_one_error(tmp_path: Path, finished_run: Path) -> None:
    out = tmp_path / "export"
    assert (
        gnp_lab("export", "tiny", "--runs-dir", finished_run.parent, "--out", out).returncode == 0
    )
    good = json.loads((out / "controller.json").read_text())
    load_controller(out / "controller.json")
    path = tmp_path / "bad.json"
    sub = good["nodes"][1]["sub_nodes"][0]
    for key, value in (("q_ss", "0.5"), ("function", True), ("beta", 1e400), ("q_ss", None)):
        bad = json.loads(json.dumps(good))
        bad["nodes"][1]["sub_nodes"][0] = {**sub, key: value}
        path.write_text(json.dumps(bad))
        with pytest.raises(ControllerFileError, match=key):
            load_controller(path)
    path.write_text("[" * (JSON_MAX_DEPTH + 1) + "]" * (JSON_MAX_DEPTH + 1))
    with pytest.raises(ControllerFileError, match="deep"):
        load_controller(path)
    path.write_text(DEEP)
    with pytest.raises(ControllerFileError, match="deep"):
        load_controller(path)
