"""What is on show, and how it plays (no viser server)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import sim
from app import store
from app.brains.registry import family_of
from app.dashboard.controls import DashboardInputError
from app.dashboard.stage import Show, Stage, random_show, run_robot
from app.phases.live import LearningSettings, LiveError, LiveSession, RobotSpec


@pytest.fixture(scope="module")
def stage() -> Stage:
    return Stage()


@pytest.fixture(scope="module")
def cs(runs_dir: Path) -> Iterator[RobotSpec]:
    with store.RunReader(runs_dir / "cs.h5") as reader:
        yield run_robot(reader)


def live(stage: Stage) -> LiveSession:
    assert stage.session is not None
    return stage.session


def poses(session: LiveSession) -> list[np.ndarray]:
    return [robot.world.poses[0] for robot in session.robots]


def assert_at(session: LiveSession, pose: np.ndarray) -> None:
    """Every robot of `session` stands at `pose` (x, y in mm; the heading modulo a turn)."""
    for actual in poses(session):
        np.testing.assert_array_equal(actual[:2], pose[:2])
        assert np.angle(np.exp(1j * (actual[2] - pose[2]))) == pytest.approx(0.0, abs=1e-12)


def show_of(robot: RobotSpec, arena: str = "training", start: int = 0, life: int = 0) -> Show:
    return Show(f"{robot.label} on show", (robot,), arena, start, life=life)


@pytest.mark.parametrize("arena", sim.ARENA_NAMES)
@pytest.mark.parametrize("start", [0, 4, sim.N_START_POSES - 1])
def test_a_runs_best_starts_at_the_arenas_start_pose(
    stage: Stage, cs: RobotSpec, arena: str, start: int
) -> None:
    session = stage.present(show_of(cs, arena, start))
    assert session is stage.session and session.arena is stage.arenas[arena]
    assert_at(session, stage.arenas[arena].start_poses[start])
    assert (stage.arena, stage.start) == (arena, start)
    assert session.robots[0].t == 0


def test_the_best_of_a_run_is_its_last_generations_best(runs_dir: Path) -> None:
    with store.RunReader(runs_dir / "bs.h5") as reader:
        last, first = run_robot(reader), run_robot(reader, 0)
        stored = family_of(reader.config).best(reader, 1)
    assert (last.label, last.family.label) == ("bs", "BS")
    np.testing.assert_array_equal(last.population.conn, stored.conn)
    assert not np.array_equal(first.population.q_ss, last.population.q_ss)


def test_restage_moves_the_robots_or_restarts_them(cs: RobotSpec) -> None:
    stage = Stage()
    staged: list[tuple[str, int]] = []
    stage.on_staged(lambda show, _session: staged.append((show.arena, show.start)))
    stage.present(show_of(cs))
    live(stage).step(30)

    stage.restage(start=3)
    assert_at(live(stage), stage.arenas["training"].start_poses[3])
    stage.restage(arena="implementation")  # the start pose stays
    implementation = stage.arenas["implementation"]
    assert_at(live(stage), implementation.start_poses[3])
    session = live(stage)
    stage.restage(arena="implementation", start=3)  # the dropdowns' echo: nothing to change
    assert live(stage) is session
    session.step(5)
    stage.restage()  # restart from the start pose
    assert live(stage) is not session and live(stage).robots[0].t == 0
    assert staged == [
        ("training", 0),
        ("training", 3),
        ("implementation", 3),
        ("implementation", 3),
    ]


def test_swap_in_keeps_the_arena_and_start_pose(cs: RobotSpec) -> None:
    stage = Stage()
    stage.swap_in("first", cs)  # nothing on show yet: the training arena, pose 0
    assert (stage.arena, stage.start) == ("training", 0)
    stage.restage(arena="implementation", start=6)
    session = stage.swap_in(
        "best of generation 1", cs, life=600, control_period=0.032, run="r", source=Path("r.h5")
    )
    assert stage.show == Show(
        "best of generation 1",
        (cs,),
        "implementation",
        6,
        life=600,
        control_period=0.032,
        runs=("r",),
        sources=(Path("r.h5"),),
    )
    assert stage.source == Path("r.h5") and stage.show.origin(1) == ("", None)
    assert_at(session, stage.arenas["implementation"].start_poses[6])


def test_advance_steps_at_the_speed_and_a_new_life_starts_from_the_next_pose(
    cs: RobotSpec,
) -> None:
    stage = Stage()
    stage.present(show_of(cs, start=sim.N_START_POSES - 2, life=20))
    stage.speed = 100.0
    assert stage.advance(0.1) == 10
    assert stage.advance(0.004) == 0  # a fraction of a step is owed, not lost
    assert stage.advance(0.007) == 1
    stage.playing = False
    assert stage.advance(1.0) == 0 and live(stage).robots[0].t == 11
    stage.playing = True
    stage.advance(0.1)  # t = 21 ≥ T = 20: a new life from the next pose
    assert stage.start == sim.N_START_POSES - 1 and live(stage).robots[0].t == 0
    stage.advance(0.2)
    assert stage.start == 0, "after the last start pose comes the first"
    stage.new_lives = False
    stage.advance(0.3)
    assert stage.start == 0 and live(stage).robots[0].t == 30
    stage.speed = 10_000.0
    assert stage.advance(1.0) == 50, "a late frame catches up at most 50 steps"


def test_noise_and_learning_carry_over_to_the_next_show(cs: RobotSpec) -> None:
    stage = Stage()
    stage.set_noise(40.0)  # before any show: kept for the first
    stage.present(show_of(cs))
    assert live(stage).robots[0].world.noise_sigma == 40.0
    offline = LearningSettings(online=False)
    stage.set_learning(offline)
    assert live(stage).learning is offline
    stage.set_noise(5.0)
    stage.restage(start=2)
    assert live(stage).robots[0].world.noise_sigma == 5.0
    assert live(stage).learning is offline


def test_breaking_stops_new_lives_and_bad_requests_change_nothing(cs: RobotSpec) -> None:
    stage = Stage()
    with pytest.raises(DashboardInputError, match="nothing on show"):
        stage.break_sensors([2], "dead")
    stage.present(show_of(cs, life=20))
    stage.break_sensors([2, 3], "stuck")
    assert stage.new_lives is False, "a fault is watched, not wiped by a new life"
    snapshot = live(stage).snapshot()[0]
    np.testing.assert_array_equal(np.flatnonzero(snapshot.broken), [2, 3])
    stage.repair()
    assert not live(stage).snapshot()[0].broken.any()

    show, session = stage.show, stage.session
    with pytest.raises(DashboardInputError, match="unknown arena 'moon'"):
        stage.restage(arena="moon")
    with pytest.raises(LiveError, match=r"start pose must be in 0\.\.9"):
        stage.restage(start=sim.N_START_POSES)
    with pytest.raises(LiveError, match="noise σ: Input should be greater than or equal to 0"):
        stage.set_noise(-1.0)
    with pytest.raises(LiveError, match="noise σ: Input should be less than or equal to 1023"):
        stage.set_noise(sim.IR_MAX + 1)
    assert (stage.show, stage.session, stage.noise_sigma) == (show, session, 0.0)
    with pytest.raises(LiveError, match="noise σ"):  # with nothing on show too
        Stage().set_noise(sim.IR_MAX + 1)


def test_a_comparison_schedules_the_same_fault_for_both_robots(
    runs_dir: Path, cs: RobotSpec
) -> None:
    with store.RunReader(runs_dir / "bs.h5") as reader:
        bs = run_robot(reader)
    stage = Stage()
    session = stage.present(
        Show("bs vs cs", (bs, cs), "implementation", 5, fault=(7, (1,), "dead"))
    )
    assert_at(session, stage.arenas["implementation"].start_poses[5])
    session.step(7)
    assert [r.fault_steps for r in session.snapshot()] == [(7,), (7,)]


def test_with_no_run_an_untrained_individual_is_shown() -> None:
    show = random_show()
    session = Stage().present(show)
    assert session.robots[0].label == "random" and show.life == 1000
    assert show.robots[0].family.label == "CS"
