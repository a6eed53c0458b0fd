"""Control validation, the genome inspector, and the training subprocess's lifecycle."""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest

import gnp
from app import store
from app.config import build_config, load_preset
from app.dashboard.controls import (
    DashboardInputError,
    TrainingRequest,
    finite,
    parse_sensors,
    training_config,
    whole,
)
from app.dashboard.training_job import TrainingJob
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
        ("8", "numbered 0..7"),
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


def request(**changes: object) -> TrainingRequest:
    fields: dict[str, object] = {
        "preset": "quick",
        "method": "BS",
        "judgment": "crisp",
        "population": 10,
        "generations": 4,
        "steps": 50,
        "noise_sigma": 30.0,
        "seed": 9,
    }
    fields.update(changes)
    return TrainingRequest(**fields)  # type: ignore[arg-type]


def test_the_train_tab_overrides_its_preset() -> None:
    config = training_config(request())
    assert config.seed == 9
    assert (config.controller.method, config.controller.fuzzy) == ("BS", False)
    training = config.training
    assert (training.population, training.generations, training.steps) == (10, 4, 50)
    assert training.noise_sigma == 30.0
    # What the form does not set comes from the preset.
    preset = load_preset("quick")
    assert config.implementation == preset.implementation
    assert config.training.redraw_every == preset.training.redraw_every


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"population": 1}, "population must be in 2..100000"),
        ({"noise_sigma": 2000.0}, "noise σ must be a number in 0..1023"),
        ({"method": "XX"}, "method must be one of RL, BS, CS"),
        ({"preset": "nope"}, "unknown preset"),
        ({"generations": 1.5}, "generations must be a whole number"),
    ],
)
def test_bad_training_fields_name_the_field(changes: dict[str, object], message: str) -> None:
    with pytest.raises(DashboardInputError, match=re.escape(message)):
        training_config(request(**changes))


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


def wait_until(condition: object, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not condition():  # type: ignore[operator]
        if time.monotonic() > deadline:
            raise AssertionError("timed out")
        time.sleep(0.1)


def generations_done(path: Path) -> int:
    """Generations a run file holds (0 while it does not exist yet)."""
    if not path.exists():
        return 0
    with store.RunReader(path) as run:
        return run.generations_done


def process_state(pid: int) -> str:
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]


def test_training_job_pauses_resumes_and_writes_a_readable_run(tmp_path: Path) -> None:
    config = build_config(
        {"seed": 1, "training": {"population": 6, "steps": 40, "generations": 400}}
    )
    job = TrainingJob(config, tmp_path / "run.h5", workers=1)
    try:
        # Past the start (numba compiles there): SIGTERM then always meets the training loop.
        wait_until(lambda: generations_done(tmp_path / "run.h5") >= 1, 120)
        job.pause()
        assert job.state == "paused"
        wait_until(lambda: process_state(job.pid) == "T", 10)  # the process really is stopped
        paused_for = job.elapsed()
        time.sleep(0.3)
        assert job.elapsed() == paused_for  # pauses do not count toward the ETA
        job.resume()
        assert job.state == "running" and process_state(job.pid) != "T"
        job.stop()
        job.wait()
        assert job.state == "stopped"
        assert "interrupted: stopped after" in job.error()  # the CLI's own message
        with store.RunReader(tmp_path / "run.h5") as run:
            assert run.config == config
            assert not run.finished
    finally:
        job.close()


def test_a_failing_training_reports_the_clis_error(tmp_path: Path) -> None:
    (tmp_path / "taken.h5").write_bytes(b"not mine")
    job = TrainingJob(build_config({}), tmp_path / "taken.h5", workers=1)
    job.wait()
    assert job.state == "failed"
    assert "already exists" in job.error()
    assert (tmp_path / "taken.h5").read_bytes() == b"not mine"
    job.close()


def test_an_empty_or_junk_runs_dir_still_serves_and_says_so(tmp_path: Path) -> None:
    import viser

    from app.dashboard.app import Dashboard

    (tmp_path / "junk.h5").write_bytes(b"not an HDF5 file")
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    dashboard = Dashboard(server, tmp_path)
    try:
        assert "no runs in" in dashboard.status.text
        assert "an untrained random CS individual" in dashboard.show.description.content
        assert "junk | ⚠ unreadable" in dashboard.runs.table.content
        session = dashboard.stage.session
        assert session is not None
        wait_until(lambda: session.robots[0].t > 0, 30)  # the live loop runs
        assert (tmp_path / "junk.h5").read_bytes() == b"not an HDF5 file"
    finally:
        dashboard.stop()
        server.stop()


def test_the_loop_plays_the_run_on_show_and_a_fault_turns_new_lives_off(runs_dir: Path) -> None:
    import viser

    from app.dashboard.app import Dashboard

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    dashboard = Dashboard(server, runs_dir, "cs")
    try:
        stage = dashboard.stage
        show = stage.show
        assert show is not None and show.life == 600 and show.start == 0  # the run's T
        stage.speed = 200.0
        wait_until(lambda: dashboard.show.start.value == "1", 30)  # a new life, echoed
        session = stage.session
        assert session is not None and session.robots[0].t < 600
        dashboard.status.guarded(None, dashboard.faults.break_now)  # sensors 2,3 by default
        assert dashboard.show.new_lives.value is False  # a fault is watched, not wiped
        assert session.snapshot()[0].broken[[2, 3]].all()
        dashboard.status.guarded(None, lambda: dashboard.show.inspect(99))
        assert dashboard.status.text == "⚠ node must be in 0..60, got 99"
    finally:
        dashboard.stop()
        server.stop()


def test_the_faults_tab_learns_with_the_fixed_values_until_a_fault(tmp_path: Path) -> None:
    import viser

    from app.dashboard.app import Dashboard
    from app.dashboard.tab_faults import SCHEDULED

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    dashboard = Dashboard(server, tmp_path)
    try:
        faults = dashboard.faults
        faults.eps_fixed.value, faults.alpha_fixed.value = 0.05, 0.2
        faults.schedule.value = SCHEDULED
        faults.eps_max.value, faults.eps_min.value = 0.015, 0.0
        faults.alpha_max.value, faults.alpha_min.value = 0.15, 0.0
        faults.horizon.value = 1000
        dashboard.status.guarded(None, faults.apply_learning)
        learning = dashboard.stage.learning
        assert learning.rates(10, None) == (0.05, 0.2)  # no fault yet: the fixed values
        assert learning.rates(600, 100) == pytest.approx((0.0075, 0.075))  # halfway down
        faults.eps_min.value = 0.5  # above its max
        dashboard.status.guarded(None, faults.apply_learning)
        assert dashboard.status.text == "⚠ a schedule's min must not exceed its max"
        assert dashboard.stage.learning is learning  # nothing applied
    finally:
        dashboard.stop()
        server.stop()
