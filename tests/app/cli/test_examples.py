"""The scripts in examples/ run as documented, and print what the run files hold."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import gymnasium
import numpy as np
import pytest

from app.store import RunReader

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def _run(script: str, *args: str) -> str:
    env = dict(os.environ, PYTHONPATH=str(EXAMPLES.parent))
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / script), *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def _number(text: str, label: str) -> float:
    match = re.search(rf"{label} (-?[0-9.]+)", text)
    assert match, text
    return float(match.group(1))


@pytest.mark.slow
def test_train_implement_and_read_a_run_as_the_examples_do(tmp_path: Path) -> None:
    run = tmp_path / "tiny.h5"
    trained = _run("train_tiny_run.py", str(run))
    implemented = _run("implement_with_a_fault.py", str(run))
    read = _run("read_a_run_with_h5py.py", str(run))
    with RunReader(run) as reader:
        history = reader.history()
        result = reader.implementation("sensors-2-3-dead")
        assert reader.config.brain.controller.method == "BS"
    best = [float(v) for v in re.findall(r"best fitness ([0-9.]+)", trained)]
    assert best == pytest.approx(history.best_fitness, abs=1e-6)
    assert _number(implemented, "after the fault") == pytest.approx(
        result.mean_after_fault, abs=1e-6
    )
    before = float(np.mean(result.reward_per_step[:100]))
    assert _number(implemented, "before the fault") == pytest.approx(before, abs=1e-6)
    assert "implementations stored: sensors-2-3-dead" in implemented
    assert "method BS, seed 3" in read
    assert _number(read, "generations done") == 3
    assert _number(read, "best fitness") == pytest.approx(history.best_fitness.max(), abs=1e-6)
    assert _number(read, "mean reward") == pytest.approx(result.mean_reward, abs=1e-6)
    plot = tmp_path / "paths.png"
    walls = _run("wall_following.py", str(run), "--steps", "200", "--plot", str(plot))
    _check_wall_following(walls, plot)


def _check_wall_following(text: str, plot: Path) -> None:
    """Both arenas are measured; reward = speed × straightness × C ≤ C, step by step, so the
    mean reward can never exceed the share of steps with C = 1."""
    for arena in ("training", "implementation"):
        line = next(row for row in text.splitlines() if row.startswith(f"{arena} arena"))
        assert "10 trials" in line
        reward = _number(line, "reward per step")
        near_wall = _number(line, r"\(C = 1\)")
        assert 0.0 <= reward <= near_wall <= 1.0, line
    assert plot.read_bytes().startswith(b"\x89PNG")


def test_an_outside_agent_on_the_gymnasium_env_as_the_example_does() -> None:
    """The example's agent knows only Gymnasium: its printed returns are what the env gives
    it, before and after add up, and losing its right-hand sensors costs it reward."""
    text = _run("wall_follow_agent.py", "--steps", "200", "--episodes", "2")
    lines = [row for row in text.splitlines() if row.startswith("episode")]
    assert len(lines) == 2
    for line in lines:
        total, before = _number(line, "return"), _number(line, "before the fault")
        after = _number(line, "after the fault")
        assert total == pytest.approx(before + after, abs=2e-3)
        assert after < _number(line, r"\(healthy control") and total <= 200
    spec = importlib.util.spec_from_file_location("agent", EXAMPLES / "wall_follow_agent.py")
    assert spec is not None and spec.loader is not None
    agent = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(agent)
    env = gymnasium.make(agent.ENV, noise=50.0, max_episode_steps=200)
    rewards = agent.episode(env, 0, None)
    assert sum(rewards[100:]) == pytest.approx(_number(lines[0], r"\(healthy control"), abs=1e-3)
    assert _number(text, "mean cost of the fault") > 0


@pytest.mark.slow
def test_gnp_cartpole_example_learns_and_prints_what_its_run_file_holds(tmp_path: Path) -> None:
    from app.tasks import read_task_run

    run = tmp_path / "cartpole.h5"
    args = ("--generations", "8", "--population", "60", "--seed", "1", "--out", str(run))
    text = _run("gnp_cartpole.py", *args)
    best = [float(v) for v in re.findall(r"best return ([0-9.]+)", text)]
    fitness = read_task_run(run).fitness
    assert best == pytest.approx(fitness.max(axis=1).tolist())
    assert len(best) == 8
    assert max(best[-3:]) > 2 * best[0]
    assert "greedy replay of the final best: return" in text
    read = _run("read_a_run_with_h5py.py", str(run))  # one format: the reader takes a task run
    assert "task CartPole-v1" in read and "implementation" not in read
    assert _number(read, "generations done") == 8
    assert _number(read, "best fitness") == pytest.approx(fitness.max(), abs=1e-6)
