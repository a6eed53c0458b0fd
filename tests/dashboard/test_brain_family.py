"""A new brain family in one file: a Braitenberg vehicle with evolved gains (issue #33).

The family below is all there is of it: a settings model, controllers, an evolution strategy and
the contract's members (`app.brains.BrainFamily`; its individuals are dicts of arrays, so
`take`, `concat` and `from_arrays` are the contract's), registered under its `name`. Nothing under
app/ names it. Its vehicles size themselves by the contract's `io` (`any_io`): 8 sensors and 2
wheels on the robot, a task's features and commands on a Gymnasium task. The tests take it
through everything the lab does with a brain: train (in worker processes, started by
`gnp-lab`), resume a cut run to the same bits, implement with a broken sensor, export, a smoke
experiment on a real Dask cluster, the dashboard in Chromium, and a Gymnasium task.

Other processes (the CLI, its workers, Dask's) find the family the way a user's would: the
module is named in `GNP_LAB_BRAINS` and importable from `PYTHONPATH`.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest
from pydantic import Field
from typing_extensions import override

import sim
from app.brains import (
    PLUGINS_VARIABLE,
    BrainFamily,
    BrainSettings,
    Evolution,
    check_family,
    family_of,
    register,
)
from app.settings.config import RunConfig
from app.settings.loading import build_config
from app.store import RunReader

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


# --- the family -------------------------------------------------------------------------------


class VehicleSettings(BrainSettings):
    """The family's own settings: the `brain` section of a run's config."""

    family: Literal["braitenberg"] = "braitenberg"
    sigma: float = Field(default=0.3, gt=0.0, le=5.0, description="mutation step of a gain")
    parents: int = Field(default=2, ge=1, description="the best that breed each generation")


@dataclass(frozen=True)
class Drive:
    """A step's trace: each wheel's drive before the clip, (N, 2)."""

    drive: np.ndarray


class Vehicles:
    """N vehicles: wheel = clip(bias + gains · readings / IR_MAX, ±1) × MAX_COMMAND (a "wheel"
    is one of the brain's outputs: the robot's wheels, a task's commands)."""

    def __init__(self, arrays: dict[str, np.ndarray]) -> None:
        self.gains, self.bias = arrays["gains"], arrays["bias"]

    @property
    def size(self) -> int:
        return len(self.gains)

    # The loop's `Controllers.act` (a protocol, named by the lab's loop alone: importing it here
    # would load the loop's kernels in every process that finds the family): a vehicle does not
    # learn, so it reads no reward.
    def act(
        self,
        observations: np.ndarray,
        reward: np.ndarray,  # noqa: ARG002
        *,
        trace: bool,
    ) -> tuple[np.ndarray, Drive | None]:
        drive = self.bias + np.einsum("nws,ns->nw", self.gains, observations / sim.IR_MAX)
        return np.clip(drive, -1.0, 1.0) * sim.MAX_COMMAND, Drive(drive) if trace else None

    def reset_episode(self) -> None:
        pass  # no memory


class VehicleEvolution(Evolution):
    """Truncation selection: the best `parents` live on, the rest are their mutated copies."""

    def __init__(self, family: Braitenberg, arrays: dict[str, np.ndarray]) -> None:
        self._family, self._arrays = family, arrays

    @override
    def epsilon_alpha(self, generation: int) -> tuple[float, float]:
        return float("nan"), float("nan")

    def individuals(self) -> dict[str, np.ndarray]:
        return self._arrays

    def arrays(self, individuals: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return individuals

    def advance(
        self, learned: dict[str, np.ndarray], fitness: np.ndarray, generation: int
    ) -> dict[str, np.ndarray]:
        settings, config = self._family.settings, self._family.config
        rng = np.random.default_rng([config.seed, generation, 0xB7])
        best = np.argsort(-fitness, kind="stable")[: settings.parents]
        rows = best[np.arange(len(fitness)) % len(best)]
        children = self._family.take(learned, rows)
        for name in ("gains", "bias"):
            noise = rng.normal(0.0, settings.sigma, children[name].shape)
            noise[: len(best)] = 0.0  # the parents themselves, unchanged
            children[name] += noise
        self._arrays = children
        return children


class Braitenberg(BrainFamily):
    """A Braitenberg vehicle: a gain from each input to each output (16 on the robot) and a
    bias per output, evolved; no learning."""

    name = "braitenberg"
    settings_model = VehicleSettings
    settings: VehicleSettings
    any_io = True  # sized by `self.io`: the robot's 8 sensors and 2 wheels, or a task's

    @property
    def description(self) -> str:
        return f"braitenberg vehicle, sigma {self.settings.sigma:g}"

    @property
    def genome_layout(self) -> dict[str, tuple[tuple[int, ...], Any]]:
        io = self.io
        return {
            "gains": ((io.n_outputs, io.n_inputs), np.float64),
            "bias": ((io.n_outputs,), np.float64),
        }

    @property
    def trace_layout(self) -> dict[str, tuple[tuple[int, ...], Any]]:
        return {"drive": ((self.io.n_outputs,), np.float64)}

    def first(self) -> VehicleEvolution:
        rng = np.random.default_rng([self.config.seed, 0xB7])
        n, io = self.config.training.population, self.io
        arrays = {
            "gains": rng.normal(0.0, 1.0, (n, io.n_outputs, io.n_inputs)),
            "bias": rng.uniform(0.0, 0.5, (n, io.n_outputs)),
        }
        return VehicleEvolution(self, arrays)

    @override
    def rebuild(
        self, generation: int, arrays: dict[str, np.ndarray], fitness: np.ndarray
    ) -> VehicleEvolution:
        return VehicleEvolution(self, self.from_arrays(arrays))  # its state is its population

    @override
    def controllers(self, individuals: dict[str, np.ndarray], engine_seeds: np.ndarray) -> Vehicles:
        return Vehicles(individuals)

    def controller_document(
        self, individual: dict[str, np.ndarray], settings: dict[str, Any]
    ) -> dict[str, Any]:
        return {
            "format": "braitenberg-controller",
            "version": 1,
            "settings": settings,
            "gains": individual["gains"][0].tolist(),
            "bias": individual["bias"][0].tolist(),
        }


register(Braitenberg)


# --- the lab, with it -------------------------------------------------------------------------

CONFIG = """
seed = 3
[brain]
family = "braitenberg"
sigma = 0.5
[training]
population = 8
generations = 4
steps = 60
shard_size = 4
noise_sigma = 20.0
[implementation]
steps = 120
repeats = 1
fault_step = 60
broken_sensors = [2]
fault_mode = "dead"
recorded_trials = 2
noise_sigma = 20.0
"""


def config() -> RunConfig:
    import tomllib

    return build_config(tomllib.loads(CONFIG))


def plugin_env() -> dict[str, str]:
    """The environment a user's process gets: this module named and importable."""
    paths = [str(HERE), str(ROOT / "tests" / "app"), os.environ.get("PYTHONPATH", "")]
    return os.environ | {
        PLUGINS_VARIABLE: Path(__file__).stem,
        "PYTHONPATH": os.pathsep.join(p for p in paths if p),
    }


def gnp_lab(*args: object, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *map(str, args)],
        capture_output=True,
        text=True,
        env=env if env is not None else plugin_env(),
        cwd=ROOT,
        timeout=600,
    )


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run cut after 2 of 4 generations (in this process), resumed by `gnp-lab` on 2
    workers: the runs dir holds it as `vehicle.h5`."""
    from app.phases.training import Control, Interrupted, train

    runs = tmp_path_factory.mktemp("vehicle-runs")
    control = Control()

    def stop_after_two(summary: Any) -> None:
        if summary.generation == 1:
            control.stop()

    with pytest.raises(Interrupted):
        train(config(), runs / "vehicle.h5", progress=stop_after_two, control=control)
    with RunReader(runs / "vehicle.h5") as run:
        assert run.generations_done == 2 and not run.finished
    done = gnp_lab("train", "--resume", runs / "vehicle.h5", "--workers", "2", "--quiet")
    assert done.returncode == 0, done.stderr
    return runs


def test_it_keeps_the_contract() -> None:
    check_family(Braitenberg)  # what its author runs first: every problem, named


def test_a_resumed_run_on_two_workers_equals_one_never_cut(trained: Path, tmp_path: Path) -> None:
    from app.phases.training import train

    train(config(), tmp_path / "whole.h5")
    with RunReader(trained / "vehicle.h5") as cut, RunReader(tmp_path / "whole.h5") as whole:
        assert cut.finished and cut.config.brain.family == "braitenberg"
        a, b = cut.history(), whole.history()
        assert np.array_equal(a.fitness, b.fitness)  # bit for bit
        assert np.array_equal(
            cut.best_genome_arrays()["gains"], whole.best_genome_arrays()["gains"]
        )
        assert np.isnan(a.epsilon).all()  # no online learning, recorded as such
        assert a.best_fitness[-1] >= a.best_fitness[0]  # the parents live on unchanged
        elite = cut.elite()
    assert elite is not None and elite.trace["drive"].shape == (1, 60, 2)


def test_the_cli_trains_it_and_refuses_a_bad_setting_on_one_line(tmp_path: Path) -> None:
    path = tmp_path / "vehicle.toml"
    path.write_text(CONFIG.replace("sigma = 0.5", "sigma = -1"), encoding="utf-8")
    bad = gnp_lab("train", "--config", path, "--out", tmp_path / "bad.h5")
    assert bad.returncode == 1 and bad.stderr.count("\n") == 1, bad.stderr
    assert "brain.sigma: " in bad.stderr
    assert "greater than 0 (got -1)" in bad.stderr
    assert not (tmp_path / "bad.h5").exists()
    unknown = gnp_lab("train", "--brain", "vehicle", "--runs-dir", tmp_path)
    assert unknown.returncode == 1 and "unknown brain family 'vehicle'" in unknown.stderr
    assert "braitenberg" in unknown.stderr  # the known ones, plug-ins included
    path.write_text(CONFIG, encoding="utf-8")
    made = gnp_lab("train", "--config", path, "--runs-dir", tmp_path, "--quiet")
    assert made.returncode == 0, made.stderr
    assert len(list(tmp_path.glob("braitenberg-seed3-*.h5"))) == 1  # named after the family
    listing = gnp_lab("runs", "--runs-dir", tmp_path).stdout
    assert "braitenberg vehicle, sigma 0.5" in listing and "finished" in listing
    # Without the plug-in the file still lists, named, not described.
    bare = os.environ | {PLUGINS_VARIABLE: ""}
    assert (
        "braitenberg (not registered)" in gnp_lab("runs", "--runs-dir", tmp_path, env=bare).stdout
    )


def test_a_broken_sensor_reaches_the_vehicle_in_the_implementation_phase(trained: Path) -> None:
    from app.phases.implementation import implement

    done = gnp_lab(
        "implement", "vehicle", "--runs-dir", trained, "--name", "broken", "--workers", 2
    )
    assert done.returncode == 0, done.stderr
    calm = config().implementation.model_copy(update={"broken_sensors": ()})
    implement(trained / "vehicle.h5", calm, name="calm")
    with RunReader(trained / "vehicle.h5") as run:
        broken = run.implementation("broken")
        intact = run.implementation("calm")
        best = family_of(run.config).best(run)
    seen = broken.trials.observations  # (2 trials, 120 steps, 8 sensors)
    assert np.all(seen[:, 60:, 2] == 0.0) and np.any(seen[:, :60, 2] > 0.0)  # dead from t'
    drive, calm_drive = broken.trials.trace["drive"], intact.trials.trace["drive"]
    assert np.array_equal(drive[:, :60], calm_drive[:, :60])  # the same life until t'
    assert not np.array_equal(drive, calm_drive)
    # The recorded drive is the vehicle's own arithmetic on what it saw.
    expected = best["bias"][0] + seen @ best["gains"][0].T / sim.IR_MAX
    np.testing.assert_allclose(drive, expected, rtol=1e-12, atol=1e-12)


def test_export_writes_its_controller_file_and_tables_without_a_graph(
    trained: Path, tmp_path: Path
) -> None:
    out = tmp_path / "export"
    done = gnp_lab("export", "vehicle", "--runs-dir", trained, "--out", out)
    assert done.returncode == 0, done.stderr
    assert "graph.dot" not in {p.name for p in out.iterdir()}
    document = json.loads((out / "controller.json").read_text(encoding="utf-8"))
    with RunReader(trained / "vehicle.h5") as run:
        best = run.best_genome_arrays()
        fitness = float(run.history().best_fitness[-1])
    assert document["format"] == "braitenberg-controller"
    assert np.array_equal(np.array(document["gains"]), best["gains"][0])
    assert document["settings"]["brain"] == "braitenberg"
    assert document["settings"]["fitness"] == fitness and "epsilon" not in document["settings"]
    assert (out / "fitness.csv").read_text(encoding="utf-8").count("\n") == 4 + 1


def _datasets(path: Path) -> dict[str, np.ndarray]:
    import h5py

    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as handle:
        handle.visititems(
            lambda name, obj: out.__setitem__(name, obj[()]) if hasattr(obj, "shape") else None
        )
    return out


def test_it_trains_resumes_and_replays_on_a_gymnasium_task(tmp_path: Path) -> None:
    from app.loop.seeds import life_seeds
    from app.phases.generations import Control, Interrupted
    from app.tasks.store import read_task_run
    from app.tasks.training import train_task

    whole, cut = tmp_path / "whole.h5", tmp_path / "cut.h5"
    sizes = ("--population", "8", "--generations", "3", "--steps", "60", "--seed", "3")
    argv = ("train", "--task", "CartPole-v1", "--brain", "braitenberg", *sizes)
    done = gnp_lab(*argv, "--out", whole, "--quiet")
    assert done.returncode == 0, done.stderr
    run = read_task_run(whole)
    assert run.config.brain == VehicleSettings() and np.isnan(run.epsilon).all()
    assert run.best_arrays()["gains"].shape == (1, 1, 4)  # CartPole: 4 features, 1 command
    control = Control()

    def stop_after_the_first(summary: Any) -> None:
        if summary.generation == 0:
            control.stop()

    with pytest.raises(Interrupted):
        train_task(run.config, cut, progress=stop_after_the_first, control=control)
    resumed = gnp_lab("train", "--resume", cut, "--quiet")
    assert resumed.returncode == 0, resumed.stderr
    a, b = _datasets(whole), _datasets(cut)
    assert sorted(a) == sorted(b)
    for name in a:  # every dataset, bit for bit (ε and α: NaN)
        assert np.array_equal(a[name], b[name], equal_nan=a[name].dtype.kind == "f"), name
    g = run.generation_done - 1
    best = int(np.argmax(run.fitness[g]))
    episode = int(life_seeds(run.config.seed, g, np.array([best]), 1, 1).world[0])
    replay = gnp_lab("replay", "whole", "--runs-dir", tmp_path, "--seed", episode)
    assert replay.returncode == 0, replay.stderr
    assert replay.stdout.startswith(f"return {run.fitness[g, best]:.1f} in ")
    listing = gnp_lab("runs", "whole", "--runs-dir", tmp_path).stdout
    assert "brain: braitenberg vehicle, sigma 0.3" in listing


EXPERIMENT = """
name = "vehicle-vs-rl"
description = "a Braitenberg vehicle against GNP-RL, smoke"
source = "tests"
preset = "thesis-ch3"
seeds = 2
[config.implementation]
broken_sensors = []
[scales.smoke]
seeds = 2
[scales.smoke.config.training]
population = 8
generations = 2
steps = 40
shard_size = 4
[scales.smoke.config.implementation]
steps = 60
fault_step = 30
repeats = 1
recorded_trials = 1

[[arms]]
name = "vehicle"
label = "Braitenberg vehicle"
config = { family = { name = "braitenberg", sigma = 0.5 } }

[[arms]]
name = "RL"
label = "GNP-RL"
config = { controller = { method = "RL" } }

[[conditions]]
name = "break-1"
label = "1 random sensor"
implementation = { break_count = 1 }

[[comparisons]]
name = "fitness"
a = "vehicle"
b = "RL"
metric = "final_best_fitness"
direction = "greater"
source = "ours"
"""


@pytest.mark.slow
def test_a_smoke_experiment_runs_it_on_a_dask_cluster(tmp_path: Path) -> None:
    spec = tmp_path / "vehicle.toml"
    spec.write_text(EXPERIMENT, encoding="utf-8")
    runs = tmp_path / "runs"
    args = ("--file", spec, "--runs-dir", runs, "--scale", "smoke")
    done = gnp_lab("experiment", "run", *args, "--workers", "2", "--quiet")
    assert done.returncode == 0, done.stderr
    files = sorted(runs.rglob("vehicle-seed*.h5"))
    assert len(files) == 2
    with RunReader(files[0]) as run:
        assert run.config.brain.family == "braitenberg" and run.finished
        assert run.implementation_names() == ["break-1"]
    report = gnp_lab("experiment", "report", *args, "--format", "json")
    assert report.returncode == 0, report.stderr


# --- on the dashboard -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def served(trained: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    from page_helpers import DEMO, dashboard_in_process

    runs = tmp_path_factory.mktemp("vehicle-dashboard")
    shutil.copyfile(DEMO, runs / "demo.h5")
    shutil.copyfile(trained / "vehicle.h5", runs / "vehicle.h5")
    # The dashboard runs an implementation in a worker process: it finds the family as any.
    with pytest.MonkeyPatch.context() as patch:
        for name, value in plugin_env().items():
            patch.setenv(name, value)
        with dashboard_in_process(runs, "demo") as dashboard:
            dashboard.stage.speed = 60.0
            yield dashboard


@pytest.mark.browser
@pytest.mark.xdist_group("dashboard-browser")
def test_the_dashboard_shows_it_drives_it_and_implements_it(served: Any, browser: Any) -> None:
    from page_helpers import choose, field, open_page, press, until, wait_for_line

    dashboard = served
    page = open_page(browser, f"http://127.0.0.1:{dashboard.server.get_port()}")
    page.get_by_role("tab", name="Runs").click()
    choose(page, "Run", "vehicle")
    press(page, "Load")
    wait_for_line(page, "vehicle", r"braitenberg vehicle, sigma 0\.5, population 8")
    press(page, "Replay best individual")
    wait_for_line(page, "on show:", r"vehicle: reward/step [\d.]+ · wheels [-+][\d.]+ [-+][\d.]+")

    page.get_by_role("tab", name="Show").click()
    wait_for_line(page, "no graph", r"no graph: this brain has none to draw")
    assert not dashboard.graph_view.visible and not dashboard.network_view.visible
    assert field(page, "Inspect node").is_disabled() and field(page, "Graph").is_disabled()
    robot = dashboard.stage.show.robots[0]
    assert robot.family.name == "braitenberg"
    # It drives: 30 steps later in this life, or a new life after the run's 60 (t starts again).
    with dashboard.lock:
        life, t = dashboard.stage.session, dashboard.stage.session.snapshot()[0].t
    until(lambda: dashboard.stage.session is not life or life.snapshot()[0].t > t + 30)

    page.get_by_role("tab", name="Runs").click()
    press(page, "Run implementation")
    match = wait_for_line(
        page,
        "on show:",
        r"implementation: vehicle/break-2-dead-[\w.-]+ · 10 trials · breaks s2 \(dead\) at 60 "
        r"· mean reward/step "
        r"([\d.]+)",
    )
    assert 0.0 <= float(match.group(1)) <= 1.0
    page.close()
