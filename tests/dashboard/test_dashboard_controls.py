"""Control validation, the genome inspector, and the training subprocess's lifecycle."""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest
from page_helpers import dashboard_in_process, until

import gnp
from app import store
from app.brains.net_settings import NetSettings
from app.dashboard.app import FRAME_SECONDS
from app.dashboard.controls import (
    DashboardInputError,
    finite,
    parse_sensors,
    training_config,
    whole,
)
from app.dashboard.training_job import TrainingJob
from app.settings.loading import build_config, load_preset
from app.views.genome import genome_view, node_label, node_markdown


@pytest.mark.parametrize(
    ("text", "sensors"),
    [("2,3", (2, 3)), (" s3 s2 ", (2, 3)), ("7;0", (0, 7)), ("4, 4", (4,))],
)
def test_sensor_lists_parse(text: str, sensors: tuple[int, ...]) -> None:
    assert parse_sensors(text) == sensors


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "at least one sensor"),
        ("2,x", "numbers 0..7"),
        ("-1", "numbers 0..7"),
    ],
)
def test_bad_sensor_lists_name_the_problem(text: str, message: str) -> None:
    with pytest.raises(DashboardInputError, match=re.escape(message)):
        parse_sensors(text)


def test_numbers_are_checked_against_their_range() -> None:
    assert whole(5.0, "generations", 1, 10) == 5
    assert finite(0.5, "ε", 0.0, 1.0) == 0.5
    with pytest.raises(DashboardInputError, match="generations must be a whole number"):
        whole(2.5, "generations", 1, 10)
    with pytest.raises(DashboardInputError, match=re.escape("generations must be in 1..10")):
        whole(0, "generations", 1, 10)
    with pytest.raises(DashboardInputError, match="ε must be a number"):
        finite(float("nan"), "ε", 0.0, 1.0)


def fields(**changes: object) -> dict[tuple[str, ...], object]:
    """What the Train tab's controls might hold, by setting path."""
    values: dict[tuple[str, ...], object] = {
        ("brain", "controller", "method"): "BS",
        ("brain", "controller", "fuzzy"): False,
        ("training", "population"): 10,
        ("training", "generations"): 4,
        ("training", "steps"): 50,
        ("training", "noise_sigma"): 30.0,
        ("seed",): 9,
    }
    values.update({tuple(key.split(".")): value for key, value in changes.items()})
    return values


def test_the_train_tab_overrides_its_preset() -> None:
    config = training_config("quick", fields())
    assert config.seed == 9
    assert (config.brain.controller.method, config.brain.controller.fuzzy) == ("BS", False)
    training = config.training
    assert (training.population, training.generations, training.steps) == (10, 4, 50)
    assert training.noise_sigma == 30.0
    # What the form does not set comes from the preset.
    preset = load_preset("quick")
    assert config.implementation == preset.implementation
    assert config.training.redraw_every == preset.training.redraw_every
    # The seed goes as far as the model allows (the tab once stopped at 2**31 - 1).
    assert training_config("quick", fields(seed=2**63 - 1)).seed == 2**63 - 1


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"training.population": 1},
            "training.population: Input should be greater than or equal to 2",
        ),
        (
            {"training.noise_sigma": 2000.0},
            "training.noise_sigma: Input should be less than or equal to 1023",
        ),
        (
            {"brain.controller.method": "XX"},
            "brain.controller.method: Input should be 'RL', 'BS' or 'CS'",
        ),
        ({"training.generations": 1.5}, "training.generations: Input should be a valid integer"),
        ({"seed": 2**63}, "seed: Input should be less than or equal to 9223372036854775807"),
        ({"training.epsilon_min": 0.5}, "epsilon_min (0.5) must not exceed epsilon_max"),
    ],
)
def test_bad_training_fields_name_the_field(changes: dict[str, object], message: str) -> None:
    with pytest.raises(DashboardInputError, match=re.escape(message)) as refused:
        training_config("quick", fields(**changes))
    assert "\n" not in str(refused.value)


def test_an_unknown_preset_is_refused() -> None:
    with pytest.raises(DashboardInputError, match="unknown preset 'nope'"):
        training_config("nope", fields())


def test_the_train_tab_trains_any_registered_family() -> None:
    assert training_config("quick", fields()).brain.family == "gnp"
    net = training_config("quick", fields(), "cmaes")
    assert net.brain == NetSettings(family="cmaes")  # GNP's controls do not apply to it
    assert net.training.population == 10  # the form's other settings still apply
    assert training_config("quick", fields(), "neat").brain.family == "neat"
    with pytest.raises(DashboardInputError, match="unknown brain family 'nope'"):
        training_config("quick", fields(), "nope")


@pytest.mark.parametrize("method", ["RL", "BS", "CS"])
def test_genome_view_and_inspector(method: str) -> None:
    cfg = gnp.GnpConfig(method=method, n_judgment=8, n_processing=4)  # type: ignore[arg-type]
    pop = gnp.init_population(cfg, 1, np.random.default_rng(0))
    pop.q_ss[0, 3] = [0.25, -0.5]
    view = genome_view(cfg, pop)
    assert view.kinds.tolist() == [0] + [1] * 8 + [2] * 4
    edges = {tuple(e) for e in view.edges.tolist()}
    # Every connection the genome holds is an edge; nothing else is.
    expected = {(0, int(pop.conn[0, 0, 0, 0, 0]))}
    for node in range(1, cfg.n_nodes):
        branches = 2 if node <= 8 else 1
        expected |= {(node, int(t)) for t in pop.conn[0, node, :, :branches].ravel()}
        if method == "CS":
            expected |= {(node, int(t)) for t in pop.credit[0, node]}
    assert edges == expected
    text = node_markdown(cfg, pop, 3)
    assert "0.250" in text and "-0.500" in text
    assert {"BS": "Q_BS", "CS": "Q_CS", "RL": "Q_SS"}[method] in text
    assert node_label(cfg, pop, 3).startswith("3 · J s")
    assert node_label(cfg, pop, 10).startswith("10 · P ")
    assert "start" in node_markdown(cfg, pop, 0)


def generations_done(path: Path) -> int:
    """Generations a run file holds (0 while it does not exist yet)."""
    if not path.exists():
        return 0
    with store.RunReader(path) as run:
        return run.generations_done


def test_training_job_pauses_resumes_and_writes_a_readable_run(tmp_path: Path) -> None:
    config = build_config(
        {"seed": 1, "training": {"population": 6, "steps": 40, "generations": 400}}
    )
    out = tmp_path / "run.h5"
    job = TrainingJob(config, out, workers=1)
    try:
        until(lambda: generations_done(out) >= 1, 120)
        job.pause()
        assert job.state == "paused"
        until(lambda: job.held, 60)  # the generation under way ends; then the run waits
        held, paused_for = generations_done(out), job.elapsed()
        time.sleep(0.3)
        assert job.held and generations_done(out) == held  # the run really is held
        assert job.elapsed() == paused_for  # pauses do not count toward the ETA
        job.resume()
        assert job.state == "running"
        until(lambda: generations_done(out) > held, 60)
        job.stop()
        assert job.state in ("stopping", "stopped")  # "stopping" until its thread ends
        job.pause()  # a pause after a stop does nothing (the run would wait, not stop)
        assert job.state in ("stopping", "stopped")
        job.wait()
        assert job.state == "stopped" and not job.active
        assert "interrupted: stopped after" in job.error()
        with store.RunReader(out) as run:
            assert run.config == config
            assert not run.finished
    finally:
        job.close()


def test_a_failing_training_reports_its_error(tmp_path: Path) -> None:
    (tmp_path / "taken.h5").write_bytes(b"not mine")
    job = TrainingJob(build_config({}), tmp_path / "taken.h5", workers=1)
    job.wait()
    assert job.state == "failed"
    assert "already exists" in job.error()
    assert (tmp_path / "taken.h5").read_bytes() == b"not mine"
    job.close()


def test_an_empty_or_junk_runs_dir_still_serves_and_says_so(tmp_path: Path) -> None:
    (tmp_path / "junk.h5").write_bytes(b"not an HDF5 file")
    with dashboard_in_process(tmp_path) as dashboard:
        assert "no runs in" in dashboard.status.text
        assert "an untrained random CS individual" in dashboard.show.description.content
        assert "junk | ⚠ unreadable" in dashboard.runs.table.content
        session = dashboard.stage.session
        assert session is not None
        until(lambda: session.robots[0].t > 0, 30)  # the live loop runs
        assert (tmp_path / "junk.h5").read_bytes() == b"not an HDF5 file"


def test_the_loop_plays_the_run_on_show_and_a_fault_turns_new_lives_off(runs_dir: Path) -> None:
    with dashboard_in_process(runs_dir, "cs") as dashboard:
        stage = dashboard.stage
        show = stage.show
        assert show is not None and show.life == 600 and show.start == 0  # the run's T
        stage.speed = 200.0
        until(lambda: dashboard.show.start.value == "1", 30)  # a new life, echoed
        session = stage.session
        assert session is not None and session.robots[0].t < 600
        dashboard.status.guarded(None, dashboard.faults.break_now)  # sensors 2,3 by default
        assert dashboard.show.new_lives.value is False  # a fault is watched, not wiped
        assert session.snapshot()[0].broken[[2, 3]].all()
        dashboard.status.guarded(None, lambda: dashboard.show.inspect(99))
        assert dashboard.status.text == "⚠ node must be in 0..60, got 99"


def test_a_control_gets_the_lock_while_frames_outlast_their_time(runs_dir: Path) -> None:
    # Frames of 0.15 s (a loaded machine) against FRAME_SECONDS = 0.1: with no pause between
    # frames, a control waited 13-35 s for the lock (Python's locks are not fair).
    with dashboard_in_process(runs_dir, "cs") as dashboard:
        stage = dashboard.stage
        advance = stage.advance

        def slow_advance(dt: float) -> None:
            busy_until = time.monotonic() + 1.5 * FRAME_SECONDS
            while time.monotonic() < busy_until:
                pass
            advance(dt)

        stage.advance = slow_advance  # type: ignore[method-assign]
        waits = []
        for _ in range(10):
            asked = time.monotonic()
            dashboard.status.guarded(None, lambda: None)
            waits.append(time.monotonic() - asked)
            time.sleep(0.05)
        assert max(waits) < 1.5, waits  # about one frame; ~13-35 s with no pause


def test_the_faults_tab_learns_with_the_fixed_values_until_a_fault(tmp_path: Path) -> None:
    from app.dashboard.tab_faults import SCHEDULED

    with dashboard_in_process(tmp_path) as dashboard:
        faults = dashboard.faults
        rate = {path[-1]: control for path, control in faults.rates.controls.items()}
        # The controls start at the implementation phase's defaults, T − t' at 3000 − 500.
        assert (rate["epsilon_max"].value, rate["alpha_max"].value) == (0.015, 0.15)
        assert faults.horizon.value == 2500 and rate["schedule_n"].value == 1.0
        rate["epsilon"].value, rate["alpha"].value = 0.05, 0.2
        faults.schedule.value = SCHEDULED
        rate["epsilon_max"].value, rate["epsilon_min"].value = 0.015, 0.0
        rate["alpha_max"].value, rate["alpha_min"].value = 0.15, 0.0
        faults.horizon.value = 1000
        dashboard.status.guarded(None, faults.apply_learning)
        learning = dashboard.stage.learning
        assert learning.rates(10, None) == (0.05, 0.2)  # no fault yet: the fixed values
        assert learning.rates(600, 100) == pytest.approx((0.0075, 0.075))  # halfway down
        rate["epsilon_min"].value = 0.5  # above its max
        dashboard.status.guarded(None, faults.apply_learning)
        assert dashboard.status.text == (
            "⚠ online learning: epsilon_min (0.5) must not exceed epsilon_max (0.015)"
        )
        rate["epsilon_min"].value = 0.0
        faults.horizon.value = 0  # below the bounds of T
        dashboard.status.guarded(None, faults.apply_learning)
        assert (
            dashboard.status.text == "⚠ T − t': Input should be greater than or equal to 1 (got 0)"
        )
        faults.noise.value = 2000  # the model's bound (the slider stops at 300)
        assert dashboard.status.text.startswith("⚠ noise σ: Input should be less than or equal")
        faults.sensors.value = "9"
        dashboard.status.guarded(None, faults.break_now)  # the world refuses sensor 9
        assert dashboard.status.text == "⚠ sensor index 9 is not in 0..7"
        assert dashboard.stage.learning is learning  # nothing applied


@pytest.mark.parametrize(
    ("state", "enabled"),
    [
        (None, {"Start"}),
        ("running", {"Pause", "Stop"}),
        ("paused", {"Resume", "Stop"}),
        ("stopping", set()),
        ("stopped", {"Start"}),
        ("finished", {"Start"}),
        ("failed", {"Start"}),
    ],
)
def test_training_buttons_follow_the_jobs_state(state: str | None, enabled: set[str]) -> None:
    from app.dashboard.tab_train import enabled_actions

    actions = enabled_actions(state)  # type: ignore[arg-type]
    assert {name for name, on in actions.items() if on} == enabled
    assert set(actions) == {"Start", "Pause", "Resume", "Stop"}


def test_the_train_tab_is_built_from_the_models(tmp_path: Path) -> None:
    from app.settings.loading import train_settings

    with dashboard_in_process(tmp_path) as dashboard:
        train = dashboard.train
        controls = train.settings.controls
        shown = {s.path for s in train_settings() if not s.optional}
        assert set(controls) == shown  # every setting a control can hold, and nothing else
        seed = controls[("seed",)]
        assert (seed.min, seed.max) == (0, 2**63 - 1)  # the model's bound, not 2**31 - 1
        c_from = controls[("reward", "c_from")]
        assert c_from.options == ("true", "observed") and c_from.value == "true"
        assert c_from.hint is not None and "readings C of Eq. 2.7 is judged from" in c_from.hint
        population = controls[("training", "population")]
        assert population.hint == "individuals [count]; 2..100000 (default 300)"
        assert population.value == load_preset("quick").training.population
        # A value from the page goes into the run's config; the preset fills in the rest.
        c_from.value = "observed"
        config = training_config("quick", train.settings.values())
        assert config.reward.c_from == "observed"
        assert config.training == load_preset("quick").training
        train.apply_preset("thesis-ch5")
        assert population.value == load_preset("thesis-ch5").training.population
        assert c_from.value == load_preset("thesis-ch5").reward.c_from
        buttons = train.buttons
        assert [buttons[n].disabled for n in ("Start", "Pause", "Resume", "Stop")] == [
            False,
            True,
            True,
            True,
        ]


def test_the_runs_and_compare_tabs_take_their_bounds_from_the_implementation_model(
    runs_dir: Path,
) -> None:
    from app.settings.config import ImplementationSettings

    fields = ImplementationSettings.model_fields
    with dashboard_in_process(runs_dir, "cs") as dashboard:
        runs, compare = dashboard.runs, dashboard.compare
        for handle, name in (
            (runs.fault_step, "fault_step"),
            (runs.steps, "steps"),
            (runs.repeats, "repeats"),
            (compare.fault_step, "fault_step"),
        ):
            bounds = {type(m).__name__: m for m in fields[name].metadata}
            assert handle.min == bounds["Ge"].ge and handle.max == bounds["Le"].le
            assert handle.hint is not None and fields[name].description in handle.hint
        runs.load_file(runs_dir / "cs.h5")
        runs.repeats.value = 0  # out of the model's range: one message, nothing started
        dashboard.status.guarded(None, runs.start_implementation)
        assert dashboard.status.text.startswith("⚠ repeats: Input should be greater than or")
        assert runs.implementation is None
