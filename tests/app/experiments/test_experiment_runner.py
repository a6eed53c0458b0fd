"""The experiment runner on real Dask clusters: results equal the run files, are the same on any
cluster and worker count, survive a killed client and a killed worker, and round-trip through
the summary file."""

from __future__ import annotations

import dataclasses
import fcntl
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np
import pytest
from experiment_fixtures import in_process_client, write_tiny
from lab_fixtures import assert_same_data

from app.experiments.cluster import NO_DASHBOARD
from app.experiments.harvest import collect, convergence_generation
from app.experiments.layout import summary_path
from app.experiments.planning import Task, inspect, plan
from app.experiments.results import ExperimentResults
from app.experiments.runner import RunOptions, run_experiment
from app.experiments.spec import ExperimentError, ExperimentSpec
from app.experiments.spec_loading import load_file
from app.experiments.summary import FORMAT, read_summary, write_summary
from app.store import RunReader

ROOT = Path(__file__).resolve().parents[3]
WORKER = ("--nworkers", "2", "--nthreads", "1")
SCALE = "small"  # of the tiny experiment: 14 generations of 12 × 1000 steps


@pytest.fixture(scope="module")
def spec(tmp_path_factory: pytest.TempPathFactory) -> ExperimentSpec:
    return load_file(write_tiny(tmp_path_factory.mktemp("spec")))


@pytest.fixture(scope="module")
def reference(spec: ExperimentSpec, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny experiment run on an in-process Dask cluster, never interrupted."""
    runs = tmp_path_factory.mktemp("reference")
    with in_process_client() as client:
        options = RunOptions(client=client, quiet=True, echo=lambda _line: None)
        run_experiment(spec, SCALE, runs, options=options)
    return runs


def _run_files(spec: ExperimentSpec, runs: Path) -> list[Path]:
    return [Path(task.path) for task in plan(spec, SCALE, runs)]


def assert_same_experiment(spec: ExperimentSpec, runs: Path, reference: Path) -> None:
    """Every run file holds the same datasets as the reference's, and so does the summary."""
    for ours, theirs in zip(_run_files(spec, runs), _run_files(spec, reference), strict=True):
        assert ours.name == theirs.name
        assert_same_data(ours, theirs)
    assert_same_results(
        read_summary(summary_path(runs, spec.name, SCALE)),
        read_summary(summary_path(reference, spec.name, SCALE)),
    )


def assert_same_results(a: ExperimentResults, b: ExperimentResults) -> None:
    for name in ("name", "description", "source", "scale", "arms", "seeds", "conditions"):
        assert getattr(a, name) == getattr(b, name), name
    assert a.comparisons == b.comparisons and a.thesis == b.thesis
    assert (a.control, a.looks, a.steps_per_run) == (b.control, b.looks, b.steps_per_run)
    for table in ("scalars", "curves"):
        left, right = getattr(a, table), getattr(b, table)
        assert sorted(left) == sorted(right)
        for key in left:
            assert np.array_equal(left[key], right[key], equal_nan=True), key


def test_results_are_the_run_files(spec: ExperimentSpec, reference: Path) -> None:
    results = read_summary(summary_path(reference, spec.name, SCALE))
    assert results.seeds == (0, 1) and results.scale == SCALE
    assert [c.name for c in results.conditions] == ["break-1", "fixed-2-3", "no-fault"]
    for task in plan(spec, SCALE, reference):
        row = results.seeds.index(task.seed)
        with RunReader(task.path) as run:
            assert run.finished and run.seed == task.seed
            history = run.history()
            assert len(history.best_fitness) == 14
            assert results.scalar("final_best_fitness", task.arm)[row] == history.best_fitness[-1]
            best = np.asarray(history.best_fitness)
            converged = int(results.scalar("convergence_generation", task.arm)[row])
            assert (
                best[converged - 1] >= 0.9 * best[-1]
                and (best[: converged - 1] < 0.9 * best[-1]).all()
            )
            assert np.array_equal(
                results.curve("best_fitness_curve", task.arm)[row], history.best_fitness
            )
            for condition in results.conditions:
                stored = run.implementation(condition.name)
                assert stored.settings.noise_sigma == 50 and stored.settings.steps == 100
                means = results.scalar("mean_reward", task.arm, condition.name)[row]
                after = results.scalar("mean_reward_after_fault", task.arm, condition.name)[row]
                assert means == stored.mean_reward and after == stored.mean_after_fault
                assert np.array_equal(
                    results.curve("reward_per_step", task.arm, condition.name)[row],
                    stored.reward_per_step,
                )
                assert np.isclose(stored.trial_mean_reward.mean(), means)
                # before the fault, from the trials' sums: the whole minus the part after it
                before = results.scalar("mean_reward_before_fault", task.arm, condition.name)[row]
                steps, cut = condition.steps, condition.fault_step
                if cut is None:  # no sensor breaks: every step is before a fault
                    assert np.isclose(before, means)
                else:
                    whole = stored.trial_mean_reward * steps
                    after_part = stored.trial_mean_after_fault * (steps - cut)
                    assert np.isclose(before, ((whole - after_part) / cut).mean())
            assert run.implementation("break-1").settings.break_count == 1
            assert run.implementation("fixed-2-3").settings.broken_sensors == (2, 3)
    # the arms differ (else the comparison would be empty), the seeds too
    fitness = results.scalar("final_best_fitness", "BS")
    assert fitness[0] != fitness[1]
    assert not np.array_equal(fitness, results.scalar("final_best_fitness", "RL"))
    assert_same_results(results, collect(spec, SCALE, reference))


def test_convergence_is_the_first_generation_at_90_percent_of_the_last() -> None:
    assert convergence_generation(np.array([1.0, 2.0, 5.0, 9.0, 10.0])) == 4.0  # 9 ≥ 0.9 · 10
    assert convergence_generation(np.array([1.0, 8.9, 9.5, 8.0, 9.9])) == 3.0  # 9.5 ≥ 8.91
    assert convergence_generation(np.array([0.0, 0.0])) == 1.0
    assert convergence_generation(np.array([3.0])) == 1.0


def test_summary_round_trip_and_partial_results(spec: ExperimentSpec, tmp_path: Path) -> None:
    results = collect(spec, SCALE, tmp_path, looks=(1, 2))  # nothing run yet: every value NaN
    assert all(np.isnan(v).all() for v in results.scalars.values())
    assert results.looks == (1, 2) and results.steps_per_run > 0
    results = dataclasses.replace(results, control="no-fault")
    results.scalars[("final_best_fitness", "BS", "")][1] = 0.25
    path = write_summary(results, tmp_path / "summary.h5")
    back = read_summary(path)
    assert_same_results(back, results)
    assert back.scalar("final_best_fitness", "BS")[1] == 0.25
    assert back.thesis[0].value == 0.158 and back.thesis[0].condition == "break-1"
    assert back.conditions[2].fault_step is None
    with h5py.File(path, "r") as handle:  # plain h5py: strings and numbers, no objects
        assert handle.attrs["format"] == FORMAT
        dataset = handle["curves/reward_per_step/RL/break-1"]
        assert dataset.shape == (2, 100) and dataset.attrs["metric"] == "reward_per_step"
        assert handle["scalars/final_best_fitness/BS/-"].dtype == np.float64

        def plain(name: str, obj: object) -> None:
            if isinstance(obj, h5py.Dataset):
                assert obj.dtype.kind in "fi", name

        handle.visititems(plain)


def test_rerun_is_idempotent(spec: ExperimentSpec, reference: Path) -> None:
    files = _run_files(spec, reference)
    before = [(p.stat().st_ino, p.stat().st_mtime_ns) for p in files]
    results = run_experiment(
        spec, SCALE, reference, options=RunOptions(quiet=True)
    )  # no cluster needed
    assert [(p.stat().st_ino, p.stat().st_mtime_ns) for p in files] == before
    assert_same_results(results, read_summary(summary_path(reference, spec.name, SCALE)))


def test_a_failed_run_does_not_hide_the_others(spec: ExperimentSpec, tmp_path: Path) -> None:
    blocked = Path(plan(spec, "smoke", tmp_path)[1].path)
    blocked.parent.mkdir(parents=True)
    lines: list[str] = []
    with (
        blocked.with_name(f".{blocked.name}.lock").open("a") as lock,
        in_process_client() as c,
    ):
        fcntl.flock(lock, fcntl.LOCK_EX)  # as if another gnp-lab process were writing it
        with pytest.raises(
            ExperimentError, match=r"1 run\(s\) failed; the first: BS-seed1: RunFileError"
        ):
            run_experiment(
                spec, "smoke", tmp_path, options=RunOptions(client=c, quiet=True, echo=lines.append)
            )
    assert sum("failed" in line for line in lines) == 1
    assert sum("final best fitness" in line for line in lines) == 3
    results = read_summary(summary_path(tmp_path, spec.name, "smoke"))
    fitness = results.scalar("final_best_fitness", "BS")
    assert np.isnan(fitness[1]) and not np.isnan(fitness[0])
    assert not np.isnan(results.scalar("mean_reward", "RL", "no-fault")).any()


@pytest.mark.slow
def test_two_worker_processes_give_identical_results(
    spec: ExperimentSpec, reference: Path, tmp_path: Path
) -> None:
    lines: list[str] = []
    run_experiment(
        spec, SCALE, tmp_path, options=RunOptions(workers=2, quiet=True, echo=lines.append)
    )
    assert len(lines) == 4 and all("final best fitness" in line for line in lines)
    assert_same_experiment(spec, tmp_path, reference)


def _pids(client: object) -> dict[str, int]:
    return client.run(os.getpid)  # type: ignore[attr-defined, no-any-return]


def _cut_run(spec: ExperimentSpec, runs: Path) -> Path | None:
    """A run file mid-training (at least one generation done), if any."""
    return _cut_run_of(plan(spec, SCALE, runs))


@pytest.mark.slow
def test_killed_worker_task_is_retried_with_identical_results(
    spec: ExperimentSpec, reference: Path, tmp_path: Path
) -> None:
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, host="127.0.0.1", **NO_DASHBOARD
        ) as cluster,
        Client(cluster) as client,
    ):
        errors: list[BaseException] = []

        def experiment() -> None:
            try:
                run_experiment(
                    spec, SCALE, tmp_path, options=RunOptions(client=client, quiet=True, echo=print)
                )
            except BaseException as error:
                errors.append(error)

        thread = threading.Thread(target=experiment)
        thread.start()
        deadline = time.monotonic() + 120
        busy: list[tuple[str, int]] = []
        while not busy and time.monotonic() < deadline:
            time.sleep(0.05)
            if _cut_run(spec, tmp_path) is not None:
                processing = client.processing()
                busy = [(a, p) for a, p in _pids(client).items() if processing.get(a)]
        victim, pid = busy[0]
        cut_keys = list(processing[victim])
        os.kill(pid, signal.SIGKILL)
        thread.join(timeout=180)
        assert not thread.is_alive() and not errors, errors
        assert pid not in _pids(client).values()  # the nanny started a new worker
    assert cut_keys and all(key.startswith("gnp-lab-run-") for key in cut_keys)
    assert_same_experiment(spec, tmp_path, reference)


def _cli(*args: str) -> subprocess.Popen[bytes]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen(
        [sys.executable, "-m", "app.cli", "experiment", *args],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,  # its own process group: the client and its whole cluster
    )


def _kill_mid_experiment(argv: list[str], tasks: list[Task]) -> bool:
    """Start the experiment and SIGKILL its process group once some runs are finished and one
    is cut; False when it finished first (the race lost: nothing was killed)."""
    first = _cli(*argv)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and first.poll() is None:
            if _complete(tasks) and _cut_run_of(tasks) is not None:
                break
            time.sleep(0.05)
        if first.poll() is not None:
            return False
        os.killpg(first.pid, signal.SIGKILL)
    finally:
        if first.poll() is None:
            os.killpg(first.pid, signal.SIGKILL)
        first.wait()
    return True


def _complete(tasks: list[Task]) -> list[Path]:
    finished = []
    for task in tasks:
        try:
            if inspect(task).complete(task):
                finished.append(Path(task.path))
        except Exception:  # being written right now
            pass
    return finished


def _cut_run_of(tasks: list[Task]) -> Path | None:
    for task in tasks:
        try:
            state = inspect(task)
        except Exception:  # being replaced right now
            continue
        if Path(task.path).exists() and state.generations_done >= 1 and not state.finished:
            return Path(task.path)
    return None


@pytest.mark.slow
def test_killed_experiment_resumes_to_identical_results(
    spec: ExperimentSpec, reference: Path, tmp_path: Path
) -> None:
    # The kill must land while some runs are finished and one is cut: on a fast, quiet machine
    # the tiny experiment can finish between two looks, so a lost race is run again (fresh).
    for attempt in range(3):
        runs = tmp_path / f"runs-{attempt}"
        argv = ["run", "--file", str(write_tiny(tmp_path)), "--scale", SCALE]
        argv += ["--runs-dir", str(runs), "--workers", "2", "--quiet"]
        tasks = plan(spec, SCALE, runs)
        if _kill_mid_experiment(argv, tasks):
            break
    else:
        pytest.fail("the tiny experiment finished before it could be killed, three times")
    # What the kill left, read after it: a run may have finished since the last look.
    done = _complete(tasks)
    cut = [Path(t.path) for t in tasks if Path(t.path).exists() and not inspect(t).finished]
    assert done and cut, "the kill should leave finished and cut runs"
    kept = {p: (p.stat().st_ino, p.stat().st_mtime_ns) for p in done}
    second = _cli(*argv)
    out, err = second.communicate(timeout=300)
    assert second.returncode == 0, err.decode()
    assert {p: (p.stat().st_ino, p.stat().st_mtime_ns) for p in done} == kept
    lines = [line for line in out.decode().splitlines() if "final best fitness" in line]
    assert len(lines) == len(tasks) - len(done)  # only the unfinished runs ran again
    assert all(RunReader(p).finished for p in cut)
    assert_same_experiment(spec, runs, reference)


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture
def external_cluster() -> Iterator[str]:
    """`dask scheduler` and `dask worker` processes on 127.0.0.1."""
    dask = str(Path(sys.executable).parent / "dask")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    common = {"env": env, "cwd": ROOT, "start_new_session": True}
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [
        subprocess.Popen(
            [dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            **common,  # type: ignore[call-overload]
            **quiet,
        )
    ]
    try:
        procs.append(
            subprocess.Popen(
                [dask, "worker", address, "--host", "127.0.0.1", "--no-dashboard", *WORKER],
                **common,  # type: ignore[call-overload]
                **quiet,
            )
        )
        yield address
    finally:
        for proc in reversed(procs):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


@pytest.mark.slow
def test_external_cluster_gives_identical_results(
    spec: ExperimentSpec,
    reference: Path,
    tmp_path: Path,
    external_cluster: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    from app.cli import main

    argv = ["experiment", "run", "--file", str(write_tiny(tmp_path)), "--scale", SCALE]
    argv += ["--runs-dir", str(tmp_path), "--scheduler", external_cluster, "--quiet"]
    assert main(argv) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert out.count("final best fitness") == 4 and "summary:" in out
    assert_same_experiment(spec, tmp_path, reference)


def test_the_cluster_it_starts_listens_on_loopback_only() -> None:
    """Safe by default: the LocalCluster `run` starts binds every server to 127.0.0.1."""
    import psutil

    from app.experiments.cluster import connect

    with connect(workers=1) as client:
        workers = set(client.run(os.getpid).values())
        nannies = {psutil.Process(pid).ppid() for pid in workers} - {os.getpid()}
        listening = [
            conn.laddr
            for pid in {os.getpid(), *workers, *nannies}
            for conn in psutil.Process(pid).net_connections(kind="inet")
            if conn.status == psutil.CONN_LISTEN
        ]
        assert listening, "the cluster listens somewhere"
        assert all(addr.ip == "127.0.0.1" for addr in listening), listening
        assert client.scheduler.address.startswith("tls://127.0.0.1:")  # and TLS (#21)
