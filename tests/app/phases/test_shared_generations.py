"""Generations through shared memory (`app.phases.shared_lives`): the same bits as in one
process, whatever the workers; a cut run resumes to the uncut one; no block outlives its run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from lab_fixtures import (
    assert_same_data,
    finish,
    generations_done,
    gnp_lab,
    tiny_config,
    wait_for,
)

import gnp
from app.loop.seeds import evolution_rng
from app.phases.generations import Control, GenerationSummary, Interrupted
from app.phases.shared_lives import EVOLVE_PARTS, evolve_part
from app.phases.training import resume, train
from app.settings.loading import build_config, to_toml
from app.store import RunReader
from app.system.workers import (
    SHARED_FOLDER,
    SHARED_PREFIX,
    SharedArrays,
    start_method,
    sweep_shared,
)


def own_blocks() -> list[str]:
    """This process's shared blocks still in /dev/shm."""
    return sorted(p.name for p in SHARED_FOLDER.glob(f"{SHARED_PREFIX}{os.getpid()}_*"))


@pytest.mark.parametrize(
    ("controller", "evolution", "population"),
    [
        ({"method": "BS", "fuzzy": True, "n_branch": 2}, {}, 300),
        ({"method": "RL"}, {}, 7),
        ({"method": "CS"}, {"judgment_pair": "independent"}, 12),
        ({"method": "BS"}, {"crossover_fraction": 0.0}, 5),
        ({"method": "RL"}, {"crossover_fraction": 0.9}, 9),
        ({"method": "RL"}, {}, 2),
        ({"method": "CS"}, {"p_add_delete": 0.5}, 12),
    ],
)
def test_the_two_halves_of_evolution_are_gnp_evolve(
    controller: dict[str, object], evolution: dict[str, object], population: int
) -> None:
    config = build_config(
        {"controller": controller, "evolution": evolution, "training": {"population": population}}
    )
    cfg, evo = config.brain.controller.gnp_config(), config.brain.evolution
    pop = gnp.init_population(cfg, population, np.random.default_rng(3))
    # Q values and genes as lives leave them: not the initial population's zeros
    rng = np.random.default_rng(4)
    for name in gnp.population.Q_FIELDS:
        getattr(pop, name)[...] = rng.normal(size=getattr(pop, name).shape)
    fitness = np.round(rng.normal(size=population), 1)  # ties, for the tournaments
    for generation in (0, 5, 9):
        expected = gnp.evolve(cfg, pop, fitness, generation, 10, evolution_rng(7, generation), evo)
        records = np.zeros_like(pop.records)
        for part in range(EVOLVE_PARTS):
            rng = evolution_rng(7, generation)
            first, rows = evolve_part(cfg, evo, pop.records, fitness, generation, 10, rng, part)
            if rows is not None:
                records[first : first + rows.size] = rows.records
        for name in gnp.population.FIELDS:  # the records' padding is never read
            assert records[name].tobytes() == expected.records[name].tobytes(), name


def test_a_run_is_the_same_on_any_number_of_workers(tmp_path: Path) -> None:
    config = tiny_config(population=13, generations=4, steps=40, shard_size=4)
    runs = {
        "one": (1, True),
        "pool-of-one": (1, False),  # both halves of evolution on the one worker
        "two": (2, True),
        "four": (4, True),
    }
    for name, (workers, local) in runs.items():
        train(config, tmp_path / f"{name}.h5", workers=workers, local=local)
        assert own_blocks() == []
    for name in runs:
        assert_same_data(tmp_path / "one.h5", tmp_path / f"{name}.h5")


def test_spawned_workers_attach_to_the_block_too(tmp_path: Path) -> None:
    # With another thread running (the dashboard's case) the pool spawns instead of forking:
    # the workers find the block by its name alone.
    config = tiny_config(population=10, generations=2, steps=30)
    train(config, tmp_path / "one.h5", workers=1)
    waiting = threading.Event()
    other = threading.Thread(target=waiting.wait)
    other.start()
    try:
        assert start_method() == "spawn"
        train(config, tmp_path / "spawned.h5", workers=2)
    finally:
        waiting.set()
        other.join()
    assert_same_data(tmp_path / "one.h5", tmp_path / "spawned.h5")
    assert own_blocks() == []


@pytest.mark.parametrize("workers", [1, 2])
def test_a_run_cut_between_checkpoints_resumes_to_the_uncut_run(
    tmp_path: Path, workers: int
) -> None:
    config = tiny_config(population=10, generations=8, steps=40, checkpoint_every=3)
    reference = tmp_path / "reference.h5"
    train(config, reference, workers=workers)
    cut = tmp_path / "cut.h5"
    control = Control()

    def stop_at_four(summary: GenerationSummary) -> None:
        if summary.generation == 3:  # four generations done; the last checkpoint is of gen. 3
            control.stop()

    with pytest.raises(Interrupted) as stopped:
        train(config, cut, workers=workers, progress=stop_at_four, control=control)
    # the file holds every generation lived to its end: 4, or 5 if the pool had already
    # lived the fifth when the stop came (the next generation's lives overlap the writing)
    assert stopped.value.generations_done in (4, 5)
    with RunReader(cut) as run:
        assert run.generations_done == stopped.value.generations_done
        point = run.checkpoint()
        assert point is not None and point[0] == 3  # generations 3.. are lived again
    resume(cut, workers=3 - workers)  # on the other number of workers
    assert_same_data(reference, cut)
    assert own_blocks() == []


def test_no_shared_block_outlives_a_failed_or_stopped_run(tmp_path: Path) -> None:
    config = tiny_config(population=10, generations=5, steps=40)

    def fail(_summary: GenerationSummary) -> None:
        assert own_blocks(), "the run works through a shared block"
        raise RuntimeError("the display broke")

    with pytest.raises(RuntimeError, match="the display broke"):
        train(config, tmp_path / "failed.h5", workers=2, progress=fail)
    assert own_blocks() == []

    def interrupt(_summary: GenerationSummary) -> None:
        raise KeyboardInterrupt  # as Ctrl-C raises it, wherever the loop is

    with pytest.raises(Interrupted):
        train(config, tmp_path / "stopped.h5", workers=2, progress=interrupt)
    assert own_blocks() == []
    with RunReader(tmp_path / "failed.h5") as run:  # the generation that failed is written
        assert run.generations_done == 1


def blocks_of(pid: int) -> list[Path]:
    return list(SHARED_FOLDER.glob(f"{SHARED_PREFIX}{pid}_*"))


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_training_process_stopped_or_killed_leaves_no_block(
    tmp_path: Path, how: signal.Signals
) -> None:
    config = tmp_path / "run.toml"
    config.write_text(to_toml(tiny_config(population=10, generations=400, steps=200)))
    out = tmp_path / "run.h5"
    process = gnp_lab("train", "--config", config, "--out", out, "--workers", "2", "--quiet")
    try:
        wait_for(lambda: generations_done(out) >= 1)
        assert blocks_of(process.pid), "the run works through a shared block"
        os.killpg(process.pid, how)  # as a terminal's Ctrl-C, `kill`, or `kill -9` of the group
        finish(process)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    if how != signal.SIGKILL:
        assert blocks_of(process.pid) == []  # unlinked by the run itself
    else:  # the resource tracker died with the group: the next block swept it
        SharedArrays.create({"x": ((1,), np.float64)}).close()
        assert blocks_of(process.pid) == []


def test_a_block_left_by_a_killed_run_is_swept() -> None:
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], check=True,
                          capture_output=True, text=True)  # fmt: skip
    left = SHARED_FOLDER / f"{SHARED_PREFIX}{int(dead.stdout)}_0badf00d"
    left.write_bytes(b"\0" * 64)
    mine = SharedArrays.create({"x": ((3,), np.float64)})  # sweeps as it creates
    try:
        assert not left.exists()
        assert own_blocks() == [mine.spec[0]]
        assert sweep_shared() == []  # a living process's block stays
        other = SharedArrays.attach(mine.spec)
        other["x"][:] = [1.0, 2.0, 3.0]
        assert mine["x"].tolist() == [1.0, 2.0, 3.0]
        other.close()  # a worker's close does not unlink
        assert own_blocks() == [mine.spec[0]]
    finally:
        mine.close()
        mine.close()  # idempotent
    assert own_blocks() == []
