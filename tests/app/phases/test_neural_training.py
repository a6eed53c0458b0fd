"""Training neural brains (CMA-ES, NEAT): workers, elite, stop/kill and resume, replay checks."""

from __future__ import annotations

import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from lab_fixtures import assert_same_data, datasets, tiny_config

import app.phases.training as training
import sim
from app.brains.net_file import NetController
from app.brains.net_settings import NetSettings
from app.brains.registry import family_of, load_controller
from app.export import ExportError, export_replay, export_run
from app.loop.seeds import life_seeds
from app.phases.implementation import implement
from app.phases.lives import live
from app.phases.training import resume, train
from app.settings.arenas import arena_of
from app.settings.config import ImplementationSettings, RunConfig
from app.settings.loading import build_config, to_toml
from app.store import RunFileError, RunReader, list_runs

OPTIMISERS = ("cmaes", "neat")


def neural_config(optimiser: str, **settings: int) -> RunConfig:
    base = tiny_config(**({"population": 10, "generations": 3} | settings))
    return build_config(base.model_dump(), {"neuro": {"optimiser": optimiser, "hidden": 4}})


@pytest.mark.parametrize("optimiser", OPTIMISERS)
def test_a_neural_run_is_the_same_on_any_worker_count(tmp_path: Path, optimiser: str) -> None:
    config = neural_config(optimiser)
    one, two = tmp_path / "one.h5", tmp_path / "two.h5"
    train(config, one, workers=1)
    train(config, two, workers=2)
    assert_same_data(one, two)
    with RunReader(one) as run:
        assert run.finished and run.config.brain.family == optimiser
        history, elite = run.history(), run.elite()
        assert elite is not None
        # The elite is the last generation's best, lived again bit for bit.
        assert elite.reward[0].sum() / config.training.steps == pytest.approx(
            history.best_fitness[-1], abs=1e-12
        )
        assert elite.trace["activation"].shape[:2] == (1, config.training.steps)
        assert np.isnan(history.epsilon).all()  # nothing learns online
    other = build_config(config.model_dump(), {"seed": 8})
    train(other, tmp_path / "other.h5", workers=1)
    assert not np.array_equal(
        datasets(one)["generations/fitness"], datasets(tmp_path / "other.h5")["generations/fitness"]
    )
    assert [s.brain for s in list_runs(tmp_path)] == [optimiser] * 3


@pytest.mark.parametrize("optimiser", OPTIMISERS)
def test_a_stopped_neural_run_resumes_to_the_uninterrupted_one(
    tmp_path: Path, optimiser: str
) -> None:
    config = neural_config(optimiser, generations=4)
    reference = train(config, tmp_path / "reference.h5", workers=1)
    np.random.seed(1)  # noqa: NPY002 (the global streams must stay untouched)
    random.seed(1)
    numpy_state, python_state = np.random.get_state()[1].copy(), random.getstate()  # noqa: NPY002

    control = training.Control()

    def stop(summary: training.GenerationSummary) -> None:
        if summary.generation == 1:
            control.stopping.set()  # what SIGTERM's handler does

    out = tmp_path / "stopped.h5"
    with pytest.raises(training.Interrupted) as stopped:
        train(config, out, workers=1, progress=stop, control=control)
    assert stopped.value.generations_done == 2
    resume(out, workers=1)
    assert_same_data(out, reference)
    assert np.array_equal(np.random.get_state()[1], numpy_state)  # noqa: NPY002
    assert random.getstate() == python_state


def test_a_resume_whose_replay_differs_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "tampered.h5"

    control = training.Control()

    def stop(_summary: training.GenerationSummary) -> None:
        control.stop()

    with pytest.raises(training.Interrupted):
        train(neural_config("cmaes"), out, workers=1, progress=stop, control=control)
    with h5py.File(out, "r+") as handle:
        told = handle["generations/fitness"][0]
        handle["generations/fitness"][0] = -told  # reversed ranks: not what the optimiser was told
    with pytest.raises(RunFileError, match="replaying the optimiser does not give"):
        resume(out, workers=1)


def test_a_killed_neural_training_resumes_to_the_uninterrupted_run(tmp_path: Path) -> None:
    # Enough generations that the kill lands mid-run however fast they go (12 once all ended
    # between two polls of the file).
    config = neural_config("neat", population=12, steps=400, generations=60)
    reference = train(config, tmp_path / "reference.h5", workers=1)
    config_file = tmp_path / "neat.toml"
    config_file.write_text(to_toml(config))
    out = tmp_path / "killed.h5"
    command = [sys.executable, "-m", "app.cli", "train", "--config", str(config_file)]
    command += ["--out", str(out), "--workers", "2", "--quiet"]
    process = subprocess.Popen(command, stderr=subprocess.PIPE, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        done = 0
        while done < 3 and time.monotonic() < deadline:
            assert process.poll() is None, process.stderr.read() if process.stderr else b""
            if out.exists():
                with RunReader(out) as run:
                    done = run.generations_done
            time.sleep(0.02)
    finally:
        os.killpg(process.pid, signal.SIGKILL)  # the trainer and its workers, mid-generation
        process.wait()
    with RunReader(out) as run:
        assert 3 <= run.generations_done < config.training.generations and not run.finished
    resume(out, workers=1)
    assert_same_data(out, reference)


@pytest.fixture(scope="module")
def neat_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished tiny NEAT run (copy it before changing it)."""
    return train(neural_config("neat"), tmp_path_factory.mktemp("neat") / "neat.h5", workers=1)


def test_a_neural_run_is_implemented_the_same_on_any_worker_count(
    tmp_path: Path, neat_run: Path
) -> None:
    settings = ImplementationSettings(
        steps=80, repeats=2, fault_step=40, break_count=2, recorded_trials=2
    )
    results = []
    for workers in (1, 2):
        path = tmp_path / f"w{workers}.h5"
        shutil.copy(neat_run, path)
        results.append(implement(path, settings, name="two", workers=workers))
        assert_same_data(path, tmp_path / "w1.h5")
    one = results[0]
    assert one.trial_mean_reward.shape == (20,)
    assert one.trials.trace["activation"].shape == (2, 80, 34)  # 2 outputs + 32 hidden


def test_an_exported_net_is_loaded_bit_identical_and_lives_the_elites_life(
    tmp_path: Path, neat_run: Path
) -> None:
    folder = export_run(neat_run, tmp_path / "export")
    controller = load_controller(folder / "controller.json")
    assert isinstance(controller, NetController)
    net, arrays, about = controller.net, controller.arrays, controller.settings
    with RunReader(neat_run) as run:
        stored = run.best_genome_arrays()
        elite = run.elite()
        config = run.config
        generation = run.generations_done - 1
        best = int(run.history().best_index[-1])
    assert elite is not None
    assert about["brain"] == "neat" and about["generation"] == generation
    assert sorted(arrays) == sorted(stored)
    assert all(np.array_equal(arrays[k], stored[k]) for k in arrays)
    training_settings = config.training
    seeds = life_seeds(config.seed, generation, np.array([best]), 1, 10)
    world = sim.World(
        arena_of(training_settings.arena),
        n=1,
        seed=config.seed,
        noise_sigma=training_settings.noise_sigma,
    )
    family = family_of(config)
    assert family.network_config == net
    _, life = live(world, family, arrays, seeds, training_settings.steps, 0, 0.0, 0.0, record=True)
    assert life is not None
    assert np.array_equal(life.poses, elite.poses)
    assert np.array_equal(life.trace["activation"], elite.trace["activation"])
    with pytest.raises(ExportError, match="is a neat run"):
        export_replay(neat_run, tmp_path / "replay")


def test_the_cli_trains_a_brain_and_lists_it(tmp_path: Path) -> None:
    command = [sys.executable, "-m", "app.cli", "train", "--brain", "cmaes", "--quiet"]
    command += ["--population", "4", "--generations", "1", "--steps", "10", "--workers", "1"]
    command += ["--runs-dir", str(tmp_path), "--set", "neuro.hidden=3"]
    subprocess.run(command, check=True, capture_output=True)
    listing = subprocess.run(
        [sys.executable, "-m", "app.cli", "runs", "--runs-dir", str(tmp_path)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    (line,) = listing.splitlines()[1:]
    assert line.startswith("cmaes-seed0-") and " cmaes: Elman net, 3 hidden " in line
    assert "finished" in line
    with RunReader(next(tmp_path.glob("*.h5"))) as run:
        assert run.config.brain == NetSettings(family="cmaes", hidden=3)


def test_the_workers_send_learned_gnp_back_but_not_the_unchanged_nets() -> None:
    from app.brains.registry import family_of
    from app.phases.generations import Evaluator

    everyone = np.arange(10)
    for config in (neural_config("cmaes"), tiny_config(population=10)):
        individuals = family_of(config).first().individuals()
        starts = len(arena_of(config.training.arena).start_poses)
        seeds = life_seeds(config.seed, 0, everyone, 1, starts)
        with Evaluator(config, 2, local=False) as pool:  # two workers, one shard each or more
            lives, after = pool.evaluate(individuals, seeds, 0.1, 0.1)
        assert lives.fitness.shape == (10,)
        if config.brain.family != "gnp":
            assert after is individuals  # nothing came back through the pipes
        else:
            assert after is not individuals and after.size == 10  # learned copies came back
            assert not np.array_equal(after.q_ss, individuals.q_ss)  # type: ignore[attr-defined]
