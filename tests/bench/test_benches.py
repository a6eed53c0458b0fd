"""Every bench under bench/ still runs against the lab's current entry points.

A bench is run only when someone measures, so an API change breaks it silently; here each one
runs at a tiny size and must print its table. Timing is the benches' job, never this test's:
what is asserted is the shape of each bench's answer, and the facts a bench checks itself
(the experiment bench's "identical results").
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RATE = r"[\d,]+"  # a rate as the benches print it: 1,234,567
RATIO = r"[\d.]+ ?[×x]"
TIMES = r"[\d.]+ /\s+[\d.]+"  # wall s / CPU s

TINY = {
    "engine": (
        "--robots 10 --steps 200 --block 50 --rounds 1",
        [rf"engine alone (RL|BS|CS)\s+{RATE} controller-steps/s"],
    ),
    "gym_env": (
        "--robots 4 --steps 20 --rounds 1",
        [rf"vector env step\s+{RATE}", rf"vector env cost / lab's world step cost: {RATIO}"],
    ),
    "limit": (
        "--robots 4 --steps 20 --rounds 1",
        [rf"rollout analytic\s+{RATE}\s+\d+", r"loop: limit of its stages [\d,]+, loop / limit"],
    ),
    "noise_stream": (
        "--population 4 --steps 20 --rounds 1",
        [rf"box-muller-v1 / ziggurat-v1: {RATIO}", r"training generation \(thesis-ch3"],
    ),
    "physics": (
        "--robots 10 --steps 200 --generations 2 --rounds 1",
        [rf"training loop, 1 worker\s+{RATE}\s+{RATE}\s+{RATIO}", r"the loop without the physics"],
    ),
    "training": (
        "--population 4 --steps 20 --generations 2 --trials 10 --impl-steps 20 --rounds 1",
        [rf"implementation, 2 workers / 1 worker: {RATIO}", r"on 2 idle cores \(from CPU s"],
    ),
    "workers": (
        "--populations 8 --steps 20 --generations 3 --rounds 1",
        [rf"2 / 1 worker: wall {RATIO}, on idle cores \(from CPU\) {RATIO}; CPU [-+][\d.]+%"],
    ),
    "working_set": (
        "--robots 8 --steps 20 --rounds 1 --pieces 4",
        [r"at once\s+\d+ ns/robot-step\s+at once / this 1\.00×", r"pieces of 4\s+\d+ ns"],
    ),
    "world": (
        "--robots 4 --steps 20 --naive-robots 2 --naive-steps 10 --repeats 1",
        [rf"iid: batched\s+{RATE} robot-steps/s.*ratio \d+×", rf"held: batched\s+{RATE}"],
    ),
    "graph": (
        f"--run {ROOT / 'saved_runs' / 'demo.h5'} --steps 20 --frames 5",
        [r"full\s+\d+\.\d\s+\d+\.\d", r"simplified\s+\d+\.\d"],
    ),
    "peer_fracnetics": (
        "--population 10 --generations 2",
        [rf"ours / fracnetics: {RATIO} env-steps per CPU second"],
    ),
    "fracnetics_twin": (
        "--population 10 --generations 2 --rounds 1",
        [rf"Acrobot-v1\s+[\d.]+\s+[\d.]+\s+{RATIO}"],
    ),
    "batch_twin": (
        "--population 10 --generations 2 --rounds 1",
        [
            rf"Pendulum-v1 {family}\s+Gymnasium [\d.]+ M/s\s+twin [\d.]+ M/s\s+{RATIO}\s+\(same"
            for family in ("gnp-rl", "cmaes")
        ],
    ),
    "tasks": (
        "--generations 2 2 2 --populations 10 --rounds 1",
        [rf"{task}-v1 N=10: compiled / Gymnasium path {RATIO}" for task in ("CartPole", "Acrobot")],
    ),
    "experiment": (
        "--seeds 1 --population 4 --generations 1 --steps 20 --workers 1",
        [r"identical results: True", rf"scale-out\s+{RATIO}"],
    ),
    "experiment_catalogue": (
        "--rounds 1",
        [
            r"experiments catalogue: 4 run files",
            rf"first read\s+[\d.]+ s\s+again\s+[\d.]+ s\s+first / again {RATIO}",
        ],
    ),
    "warm_workers": (
        "--rounds 1",
        [r"cold worker\s+first task\s+[\d.]+ s", r"with WarmWorkers\s+first task"],
    ),
    "cli_startup": (
        "--rounds 1",
        [rf"gnp-lab (--help|runs)\s+lazy\s+{TIMES}\s+eager\s+{TIMES}\s+eager / lazy\s+{RATIO}"],
    ),
    "profile_loop": (
        "--robots 4 --steps 20 --lives 1 --pid-file /dev/null",
        [rf"\d+ numba symbols mapped; rollout analytic {RATE} robot-steps per CPU second"],
    ),
    "dashboard_latency": (
        "--seconds 3",
        [r"\d+ control actions during training.*median [\d.]+ ms, p95 [\d.]+ ms"],
    ),
}


def bench(name: str, arguments: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run bench/`name`.py with `arguments` (split on spaces) in this interpreter."""
    return subprocess.run(
        [sys.executable, str(ROOT / "bench" / f"{name}.py"), *arguments.split()],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=ROOT,
    )


@pytest.mark.parametrize("name", sorted(TINY))
def test_a_bench_prints_its_table(name: str) -> None:
    arguments, rows = TINY[name]
    done = bench(name, arguments)
    assert done.returncode == 0, done.stderr[-3000:]
    for row in rows:
        assert re.search(row, done.stdout), f"{row!r} not in:\n{done.stdout}"


def test_versus_runs_a_tree_against_itself() -> None:
    """It compares trees side by side; here this tree is its own baseline."""
    tiny = "--population 4 --steps 10 --trials 10 --impl-steps 20 --rounds 1 --workers 1"
    done = bench("versus", f"--baseline {ROOT} {tiny}")
    assert done.returncode == 0, done.stderr
    number = r"\s+[\d.]+ /\s+[\d.]+"
    for case in ("training generation, 1 worker", "implementation block, 1 worker"):
        row = rf"{case}\s+this tree{number}\s+baseline{number}\s+baseline / this tree\s+[\d.]+×"
        assert re.search(row, done.stdout), done.stdout
    assert "implementation 10 trials × 20 steps" in done.stdout


def test_kernels_runs_a_tree_against_itself() -> None:
    """Issue #48's bench compares trees side by side; here this tree is its own baseline."""
    tiny = "--population 4 --steps 10 --loop-steps 10 --rounds 1"
    done = bench("kernels", f"--baseline {ROOT} {tiny}")
    assert done.returncode == 0, done.stderr[-3000:]
    for case in ("training generation", "compiled loop"):
        row = rf"{case}\s+this tree\s+[\d.]+\s+baseline\s+[\d.]+\s+baseline / this tree\s+[\d.]+×"
        assert re.search(row, done.stdout), done.stdout
    assert re.search(
        r"generation target ≥ 1.4× the baseline's speed: [\d.]+×, (not )?met", done.stdout
    )
    assert re.search(r"this tree: compiled loop [\d.]+ M robot-steps per CPU second", done.stdout)


def test_every_bench_is_run_by_a_test() -> None:
    """A new bench joins TINY (or has a test of its own), so it cannot rot unseen either."""
    tested = set(TINY) | {"versus", "versus_kheperax", "soak", "kernels"}
    assert {path.stem for path in (ROOT / "bench").glob("*.py")} == tested


def test_our_side_of_versus_kheperax_and_its_missing_peer() -> None:
    """Our side prints its timing as JSON; without kheperax the driver says so on one line."""
    ours = bench("versus_kheperax", "--side box-muller-v1 --robots 4 --steps 20 --repeats 1")
    assert ours.returncode == 0, ours.stderr[-3000:]
    assert re.fullmatch(r'\{"cpu": [\d.e-]+, "wall": [\d.e-]+\}\n', ours.stdout)
    missing = bench("versus_kheperax", "--kheperax-python /no/such/python --rounds 1")
    assert missing.returncode == 2
    assert missing.stderr.strip().splitlines()[-1] == (
        "versus_kheperax.py: error: /no/such/python cannot import kheperax; install it in a venv "
        "of its own (see this file's docstring) and pass that venv's python as --kheperax-python"
    )
    assert "Traceback" not in missing.stderr


@pytest.mark.parametrize(
    ("name", "arguments", "message"),
    [
        ("physics", "--generations 1", "--generations must be at least 2 (got 1)"),
        ("training", "--trials 4", "--trials must be at least 10 (got 4)"),
        ("workers", "--generations 2", "--generations must be at least 3 (got 2)"),
    ],
)
def test_a_size_no_bench_can_time_is_refused(name: str, arguments: str, message: str) -> None:
    done = bench(name, arguments)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].endswith(f"error: {message}")


@pytest.mark.browser
def test_soak_serves_the_runs_to_a_browser(tmp_path: Path) -> None:
    """The soak bench keeps a Chromium tab on the dashboard and samples the server's memory."""
    shutil.copy(ROOT / "saved_runs" / "demo.h5", tmp_path / "demo.h5")
    arguments = f"--minutes 0.1 --tabs 1 --every 2 --runs-dir {tmp_path}"
    done = bench("soak", arguments)
    assert done.returncode == 0, done.stderr[-3000:]
    samples = re.findall(r"^\s+[\d.]+\s+([\d.]+)\s+(\d+)$", done.stdout, flags=re.MULTILINE)
    assert len(samples) >= 2, done.stdout
    steps = [int(step) for _, step in samples]
    assert steps == sorted(steps) and steps[-1] > steps[0]  # the robot drove on between samples
    assert re.search(r"RSS first [\d.]+ MiB, max [\d.]+ MiB, last [\d.]+ MiB", done.stdout)
