"""Fault injection: a full disk, SIGKILL at seeded random moments of train / implement /
experiment, a killed Dask worker, a corrupt file in each reader. Each asserts the exit status,
the one-line message, and that finished data is bit-identical to an undisturbed run."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from experiment_fixtures import write_tiny
from lab_fixtures import (
    assert_same_data,
    file_digest,
    finish,
    generations_done,
    gnp_lab,
    tiny_config,
)

from app.cli import main
from app.experiments.planning import plan
from app.experiments.spec_loading import load_file
from app.phases.implementation import implement
from app.phases.training import train
from app.settings.loading import to_toml
from app.store import RunReader

MOMENTS = 10
RNG_SEED = 21  # the kill moments are drawn from this seed: the same moments on every run


def _kill_after(process: subprocess.Popen[bytes], seconds: float) -> bool:
    """SIGKILL `process`'s group after `seconds` unless it ended first; whether it was killed."""
    try:
        process.wait(timeout=seconds)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        return True
    return False


def _leftovers(folder: Path) -> list[str]:
    """Temporary and lock files anywhere under `folder`."""
    return sorted(
        str(p.relative_to(folder)) for p in folder.rglob(".*") if p.name.endswith((".tmp", ".lock"))
    )


def _one_error_line(err: str, *needles: str) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err, err
    assert lines and lines[-1].startswith("gnp-lab: error: "), err
    assert sum(line.startswith("gnp-lab: error: ") for line in lines) == 1, err
    for needle in needles:
        assert needle in lines[-1], err


# --- SIGKILL at seeded random moments -------------------------------------------------------


KILL_GENERATIONS = 24
IMPLEMENT = ("--repeats", "6", "--steps", "1000", "--fault-step", "500", "--break", "2,3")


@pytest.fixture(scope="module")
def kill_config(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, float]:
    """(config file, its undisturbed run, implemented once as `fault`, the median seconds of
    one of its generations: kills land within a generation however fast the machine is)."""
    folder = tmp_path_factory.mktemp("kill")
    # Generations of some milliseconds each (40k robot-steps): a kill can land inside one.
    config = tiny_config(population=16, steps=2500, generations=KILL_GENERATIONS, shard_size=8)
    config_file = folder / "kill.toml"
    config_file.write_text(to_toml(config))
    reference = folder / "reference.h5"
    seconds: list[float] = []
    train(config, reference, workers=1, progress=lambda summary: seconds.append(summary.seconds))
    shutil.copy(reference, folder / "trained.h5")  # the run before its implementation
    assert main(["implement", "reference", "--runs-dir", str(folder), "--name", "fault",
                 "--quiet", "--workers", "1", *IMPLEMENT]) == 0  # fmt: skip
    return config_file, reference, float(np.median(seconds))


def _moments(low: float, high: float, count: int = MOMENTS) -> list[float]:
    return list(np.random.default_rng(RNG_SEED).uniform(low, high, count))


@pytest.mark.slow
def test_train_killed_at_ten_moments_resumes_to_identical_data(
    tmp_path: Path, kill_config: tuple[Path, Path, float]
) -> None:
    """Moment i: once the file holds g_i generations (seeded, rising), a seeded fraction of a
    generation later (of the reference run's median generation: a fixed delay outlasted the
    generations left once the compiled loop made them a few milliseconds each); g_0 = 0 kills
    while the file is being created or just after."""
    config_file, reference, generation_seconds = kill_config
    out = tmp_path / "run.h5"
    rng = np.random.default_rng(RNG_SEED)
    targets = np.sort(rng.choice(np.arange(1, KILL_GENERATIONS - 1), MOMENTS - 1, replace=False))
    for target, fraction in zip([0, *targets], rng.uniform(0.0, 1.0, MOMENTS), strict=True):
        if out.exists():
            with RunReader(out) as run:  # what a kill left opens, and is not finished
                assert not run.finished
                has_checkpoint = run.checkpoint() is not None
            if not has_checkpoint:  # killed between creating the file and its first data
                out.unlink()
        if out.exists():
            process = gnp_lab("train", "--resume", out, "--quiet", "--workers", "1")
        else:
            process = gnp_lab("train", "--config", config_file, "--out", out, "--quiet")
        while process.poll() is None and generations_done(out) < target:
            time.sleep(0.005)
        delay = float(fraction) * generation_seconds
        assert _kill_after(process, delay), "the run ended before its kill"
    with RunReader(out) as run:
        finished = run.finished
    if not finished:  # the last kill may land after the run is complete, as its process exits
        status, err = finish(gnp_lab("train", "--resume", out, "--quiet", "--workers", "1"))
        assert status == 0, err
    assert_same_data(out, reference.with_name("trained.h5"))
    assert _leftovers(tmp_path) == []


@pytest.mark.slow
def test_implement_killed_at_ten_moments_leaves_the_run_intact(
    tmp_path: Path, kill_config: tuple[Path, Path, float]
) -> None:
    _, reference, _ = kill_config
    out = tmp_path / "run.h5"
    with RunReader(reference) as run:
        config = run.config
    train(config, out, workers=1)  # the run as training left it
    before = file_digest(out)
    implement_args = ("implement", "run", "--runs-dir", tmp_path, "--name", "fault", "--quiet",
                      "--workers", "1", *IMPLEMENT)  # fmt: skip
    timing = tmp_path / "timing"
    timing.mkdir()
    took = float("inf")  # of a whole `implement`, start-up included: the faster of two, so a
    for _ in range(2):  # slow first one (caches loading, a busy machine) does not push the
        shutil.copy(out, timing / "run.h5")  # kills past the end
        began = time.monotonic()
        status, err = finish(gnp_lab(*implement_args[:3], timing, *implement_args[4:]))
        took = min(took, time.monotonic() - began)
        assert status == 0, err
    pristine = timing / "pristine.h5"
    shutil.copy(out, pristine)
    # Ten kills at seeded moments: an implementation that a faster spell of a busy machine lets
    # finish first is checked the same way, and the next moment is drawn (at most ten of those).
    kills = tries = replaced = 0
    for moment in _moments(0.05 * took, 0.9 * took, 2 * MOMENTS):
        if kills == MOMENTS:
            break
        kills += _kill_after(gnp_lab(*implement_args), moment)
        tries += 1
        # Untouched, or (killed after its rename, or finished first) holding the whole result.
        if file_digest(out) != before:
            assert_same_data(out, reference)
            shutil.copy(pristine, out)  # back to the trained run for the next moment
            replaced += 1
    # At least 3 kills cut an implementation before its rename (the file untouched): on a
    # loaded machine the moments drift late, and half of them landing after it is no defect.
    assert kills == MOMENTS and tries - replaced >= 3, (kills, tries, replaced)
    status, err = finish(gnp_lab(*implement_args))
    assert status == 0, err
    assert_same_data(out, reference)
    assert _leftovers(tmp_path) == []


@pytest.mark.slow
def test_experiment_killed_at_ten_moments_resumes_to_identical_data(tmp_path: Path) -> None:
    spec_file = write_tiny(tmp_path)
    spec = load_file(spec_file)
    reference, runs = tmp_path / "reference", tmp_path / "runs"
    run = ("experiment", "run", "--file", spec_file, "--scale", "smoke", "--quiet")
    began = time.monotonic()
    status, err = finish(gnp_lab(*run, "--runs-dir", reference, "--workers", "1"), 90)
    took = time.monotonic() - began  # of a whole run, start-up included
    assert status == 0, err
    kills = sum(
        _kill_after(gnp_lab(*run, "--runs-dir", runs, "--workers", "2"), moment)
        for moment in sorted(_moments(0.05 * took, 0.9 * took))
    )
    # Each resume has less left to do than the one before, so the later moments may come after
    # its end (how many depends on the machine's speed); the early ones always cut a run.
    assert kills >= 3, kills
    status, err = finish(gnp_lab(*run, "--runs-dir", runs, "--workers", "2"))
    assert status == 0, err
    for ours, theirs in zip(plan(spec, "smoke", runs), plan(spec, "smoke", reference), strict=True):
        assert_same_data(Path(ours.path), Path(theirs.path))
    assert _leftovers(runs) == []


def test_a_second_experiment_run_is_refused_while_one_runs(tmp_path: Path) -> None:
    from app.experiments.layout import experiment_dir
    from app.experiments.lock import experiment_lock

    spec_file = write_tiny(tmp_path)
    with experiment_lock(experiment_dir(tmp_path / "runs", "tiny")):
        status, err = finish(
            gnp_lab("experiment", "run", "--file", spec_file, "--scale", "smoke",
                     "--runs-dir", tmp_path / "runs")
        )  # fmt: skip
    assert status == 1
    _one_error_line(err, "already running (pid", str(os.getpid()))
    assert _leftovers(tmp_path / "runs") == []  # released: no lock file left


# --- a killed Dask worker on the TLS cluster ------------------------------------------------


@pytest.mark.slow
def test_a_killed_worker_of_the_tls_cluster_is_replaced_and_results_identical(
    tmp_path: Path,
) -> None:
    import threading

    from app.experiments.cluster import connect
    from app.experiments.runner import RunOptions, run_experiment

    spec = load_file(write_tiny(tmp_path))
    reference = tmp_path / "reference"
    run_experiment(spec, "smoke", reference, options=RunOptions(quiet=True, client=None, workers=1))
    runs = tmp_path / "runs"
    with connect(workers=2) as client:
        assert client.scheduler.address.startswith("tls://")
        errors: list[BaseException] = []

        def experiment() -> None:
            try:
                run_experiment(spec, "smoke", runs, options=RunOptions(client=client, quiet=True))
            except BaseException as error:
                errors.append(error)

        thread = threading.Thread(target=experiment)
        thread.start()
        deadline = time.monotonic() + 120
        busy: list[int] = []
        while not busy and time.monotonic() < deadline and thread.is_alive():
            time.sleep(0.05)
            processing = client.processing()
            pids = client.run(os.getpid)
            busy = [pid for address, pid in pids.items() if processing.get(address)]
        assert busy, "no worker was busy"
        os.kill(busy[0], signal.SIGKILL)
        thread.join(timeout=240)
        assert not thread.is_alive() and not errors, errors
    for ours, theirs in zip(plan(spec, "smoke", runs), plan(spec, "smoke", reference), strict=True):
        assert_same_data(Path(ours.path), Path(theirs.path))


# --- a full disk ----------------------------------------------------------------------------


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 1 MiB tmpfs (root only: CI runs as root)."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a small tmpfs to fill needs root")
    mount = tmp_path / "disk"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount)])
    if done.returncode != 0:
        pytest.skip("this machine does not let root mount a tmpfs (a container without it)")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


def test_training_on_a_full_disk_stops_on_one_line_and_resumes_identically(
    tmp_path: Path, small_disk: Path
) -> None:
    config = tiny_config(population=40, steps=60, generations=60, shard_size=40)
    config_file = tmp_path / "c.toml"
    config_file.write_text(to_toml(config))
    reference = tmp_path / "reference.h5"
    train(config, reference, workers=1)
    out = small_disk / "run.h5"
    (small_disk / "ballast").write_bytes(bytes(512 * 1024))  # leaves ~0.5 MiB
    status, err = finish(gnp_lab("train", "--config", config_file, "--out", out, "--quiet"))
    assert status == 1
    _one_error_line(err, "no space left on the disk", "--resume")
    with RunReader(out) as run:
        done = run.generations_done
        assert 0 < done < config.training.generations and run.checkpoint() is not None
    moved = tmp_path / "moved.h5"
    shutil.copy(out, moved)
    train_resume = gnp_lab("train", "--resume", moved, "--quiet")
    assert finish(train_resume)[0] == 0
    assert_same_data(moved, reference)
    assert _leftovers(small_disk) == []


def test_implementing_on_a_full_disk_leaves_the_run_intact(
    finished_run: Path, small_disk: Path
) -> None:
    out = small_disk / "run.h5"
    shutil.copy(finished_run, out)
    free = shutil.disk_usage(small_disk).free
    (small_disk / "ballast").write_bytes(bytes(max(0, free - 80 * 1024)))
    before = file_digest(out)
    status, err = finish(
        gnp_lab("implement", "run", "--runs-dir", small_disk, "--quiet", "--workers", "1")
    )
    assert status == 1
    _one_error_line(err, "no space left on the disk", "implementation")
    assert file_digest(out) == before
    assert _leftovers(small_disk) == []


# --- a corrupt file in each reader ----------------------------------------------------------

GARBAGE = b"\x89HDF\r\n\x1a\n" + bytes(range(256)) * 4  # an HDF5 signature, then noise


@pytest.mark.parametrize(
    ("name", "command", "needle"),
    [
        ("run.h5", ("runs", "run"), "run.h5"),
        ("run.h5", ("implement", "run"), "run.h5"),
        ("run.h5", ("train", "--resume", "{dir}/run.h5"), "run.h5"),
        ("c.toml", ("train", "--config", "{dir}/c.toml"), "c.toml"),
        ("a.json", ("train", "--set", "training.arena={dir}/a.json"), "a.json"),
        ("e.toml", ("experiment", "run", "--file", "{dir}/e.toml"), "e.toml"),
        ("run.h5", ("export", "run", "--out", "{dir}/x"), "run.h5"),
    ],
)
def test_a_corrupt_file_ends_in_one_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    name: str,
    command: tuple[str, ...],
    needle: str,
) -> None:
    (tmp_path / name).write_bytes(GARBAGE)
    args = [part.replace("{dir}", str(tmp_path)) for part in command]
    if args[0] in ("runs", "implement", "export"):
        args += ["--runs-dir", str(tmp_path)]
    assert main(args) == 1
    _one_error_line(capsys.readouterr().err, needle)


def test_a_corrupt_summary_ends_in_one_line(tmp_path: Path) -> None:
    from app.experiments.summary import read_summary

    path = tmp_path / "summary-smoke.h5"
    path.write_bytes(GARBAGE)
    with pytest.raises(Exception, match="summary") as caught:
        read_summary(path)
    assert "\n" not in str(caught.value)


def test_a_run_file_naming_a_path_is_refused_without_reading_it(
    tmp_path: Path, finished_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import h5py

    path = tmp_path / "run.h5"
    shutil.copy(finished_run, path)
    with h5py.File(path, "r+") as handle:
        text = str(handle.attrs["config"])
        arena = RunReader(finished_run).config.implementation.arena.model_dump_json()
        handle.attrs["config"] = text.replace(arena, '"/dev/zero"')
    assert main(["implement", "run", "--runs-dir", str(tmp_path), "--quiet"]) == 1
    _one_error_line(capsys.readouterr().err, "invalid config", "/dev/zero", "inline")


def test_an_old_run_file_naming_shipped_arenas_loads_them_inline(
    tmp_path: Path, finished_run: Path
) -> None:
    """Run files written before arenas were inline stored their names: these resolve to the
    shipped arenas, so the config equals the one a new run of it stores."""
    import h5py

    from app.settings.arenas import shipped_spec

    path = tmp_path / "old.h5"
    shutil.copy(finished_run, path)
    with RunReader(finished_run) as run:
        config = run.config
    with h5py.File(path, "r+") as handle:
        text = str(handle.attrs["config"])
        for phase in ("training", "implementation"):
            spec_json = getattr(config, phase).arena.model_dump_json()
            assert spec_json in text
            text = text.replace(spec_json, f'"{phase}"')
        assert '"arena":"training"' in text  # as an old gnp-lab wrote it
        handle.attrs["config"] = text
    with RunReader(path) as run:
        assert run.config == config
        assert run.config.training.arena == shipped_spec("training")
        assert run.config.implementation.arena == shipped_spec("implementation")
    result = implement(path, config.implementation.model_copy(update={"repeats": 1}), name="x")
    assert result.trial_mean_reward.shape == (10,)
