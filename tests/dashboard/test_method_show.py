"""The RL/BS/CS switch: the bundled runs of each method put on show, one or all three, in the
arena, start pose and faults on show now; the stage's chosen robot."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest

from app import store
from app.dashboard import method_show
from app.dashboard.controls import DashboardInputError
from app.dashboard.method_show import ALL_THREE, BUNDLED, bundled_run, show_methods
from app.dashboard.stage import Stage, run_robot


@pytest.fixture(scope="module")
def trio(runs_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A runs dir with a run file under each bundled name (tiny runs: bs and cs twice)."""
    folder = tmp_path_factory.mktemp("trio")
    for method, name in BUNDLED.items():
        source = runs_dir / ("bs.h5" if method == "BS" else "cs.h5")
        shutil.copy(source, folder / f"{name}.h5")
    return folder


def test_one_method_is_its_bundled_runs_final_best(trio: Path) -> None:
    stage = Stage()
    stage.restage()  # nothing on show: nothing to restage
    show_methods(stage, trio, "BS")
    show = stage.show
    assert show is not None and len(show.robots) == 1
    assert show.runs == (BUNDLED["BS"],) and show.sources == (trio / f"{BUNDLED['BS']}.h5",)
    with store.RunReader(trio / f"{BUNDLED['BS']}.h5") as reader:
        expected = run_robot(reader)
        assert show.life == reader.config.training.steps
    for field in dataclasses.fields(expected.population):
        got, want = (
            getattr(show.robots[0].population, field.name),
            getattr(expected.population, field.name),
        )
        np.testing.assert_array_equal(got, want)


def test_all_three_keep_the_arena_pose_and_the_broken_sensors(trio: Path) -> None:
    stage = Stage()
    show_methods(stage, trio, "CS")
    stage.restage(arena="implementation", start=4)
    stage.break_sensors([2, 5], "stuck")
    show_methods(stage, trio, ALL_THREE)
    show, session = stage.show, stage.session
    assert show is not None and session is not None
    assert show.runs == tuple(BUNDLED.values())  # RL, BS, CS: one colour each, in this order
    assert (show.arena, show.start) == ("implementation", 4)
    for robot in session.snapshot():  # broken from the first step, in the same mode
        assert robot.t == 0
        assert list(np.flatnonzero(robot.broken)) == [2, 5] and robot.fault_mode == "stuck"
    assert stage.faults == ((2, 5), "stuck")
    stage.repair()
    show_methods(stage, trio, "RL")
    assert stage.faults is None


def test_the_chosen_robot_draws_and_tells_the_panels(trio: Path) -> None:
    stage = Stage()
    seen: list[tuple[str, int]] = []
    stage.on_staged(lambda show, _: seen.append((show.title, stage.selected)))
    show_methods(stage, trio, ALL_THREE)
    stage.select(2)
    assert stage.source == trio / f"{BUNDLED['CS']}.h5"
    assert [s for _, s in seen] == [0, 2]
    with pytest.raises(DashboardInputError, match=r"robot must be in 1\.\.3, got 4"):
        stage.select(3)
    show_methods(stage, trio, "RL")  # one robot: the choice falls back to it
    assert stage.selected == 0 and stage.source == trio / f"{BUNDLED['RL']}.h5"


def test_missing_or_unknown_methods_are_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(method_show, "CHECKOUT_RUNS", tmp_path / "nowhere")
    with pytest.raises(DashboardInputError, match=r"the bundled RL run demo-rl\.h5 is in neither"):
        bundled_run(tmp_path, "RL")
    with pytest.raises(DashboardInputError, match="method must be one of RL, BS, CS"):
        bundled_run(tmp_path, "PPO")
    with pytest.raises(DashboardInputError, match="show must be one of"):
        show_methods(Stage(), tmp_path, "all")


def test_the_checkout_keeps_a_bundled_run_of_every_method() -> None:
    """The three bundled runs: chapter 5's preset, seed 0, 1000 generations, each its method."""
    configs = {}
    for method in BUNDLED:
        name, path = bundled_run(Path("/nonexistent"), method)
        assert name.endswith("(bundled)") and path.stat().st_size < 11_000_000
        with store.RunReader(path) as reader:
            assert reader.generations_done == reader.config.training.generations == 1000
            configs[method] = reader.config
    assert {m: c.brain.controller.method for m, c in configs.items()} == {m: m for m in BUNDLED}
    first = configs["CS"].model_dump()
    for config in configs.values():  # only the method (and its sub nodes) differ
        other = config.model_dump()
        assert other["seed"] == first["seed"] and other["training"] == first["training"]
        assert other["brain"]["evolution"] == first["brain"]["evolution"]
