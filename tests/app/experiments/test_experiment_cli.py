"""`gnp-lab experiment`: the happy path, and every mistake ends in one line, a non-zero exit
and nothing written or overwritten."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from experiment_fixtures import TINY_TOML, tiny_data, to_toml, write_tiny
from lab_fixtures import file_digest, one_error_line, tiny_config

from app.cli import main
from app.experiments.cli import _core_time
from app.experiments.planning import plan
from app.experiments.results import CORE_STEPS_PER_SECOND, VERDICTS
from app.experiments.spec_loading import load_file
from app.experiments.summary import read_summary
from app.phases.implementation import implement
from app.phases.training import train
from app.settings.loading import build_config
from app.store import RunReader


def _files(folder: Path) -> dict[Path, str]:
    return {p: file_digest(p) for p in sorted(folder.rglob("*")) if p.is_file()}


BAD_FILES = [
    ("unknown arm", TINY_TOML.replace('a = "BS"', 'a = "CS"', 1), "unknown arm 'CS'"),
    ("unknown metric", TINY_TOML.replace('"final_best_fitness"', '"speed"'), "unknown metric"),
    ("duplicate", TINY_TOML.replace('name = "RL"', 'name = "BS"'), "duplicate arm name"),
    ("bad value", TINY_TOML.replace("break_count = 1", "break_count = 11"), "break_count"),
    ("not toml", "name = ", "not valid TOML"),
]


@pytest.mark.parametrize(
    ("text", "needle"), [b[1:] for b in BAD_FILES], ids=[b[0] for b in BAD_FILES]
)
@pytest.mark.parametrize("verb", ["run", "status", "report"])
def test_bad_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], verb: str, text: str, needle: str
) -> None:
    path = write_tiny(tmp_path, text)
    runs = tmp_path / "runs"
    argv = ["experiment", verb, "--file", str(path), "--runs-dir", str(runs), "--scale", "smoke"]
    assert main(argv) == 1
    one_error_line(capsys, needle, str(path))
    assert not runs.exists()


@pytest.mark.parametrize(
    ("argv", "code", "needle"),
    [
        (["run", "ch9"], 1, "no shipped experiment named 'ch9'"),
        (["run", "../../etc"], 1, "no shipped experiment"),
        (["status"], 1, "give an experiment NAME"),
        (["run", "ch3-bs-rl", "--scale", "huge"], 2, "invalid choice: 'huge'"),
        (["run", "ch3-bs-rl", "--seeds", "0"], 2, "--seeds"),
        (["run", "ch3-bs-rl", "--workers", "-1"], 2, "--workers"),
        (["run", "ch3-bs-rl", "--scheduler", "tcp://127.0.0.1:1", "--workers", "2"], 1, "drop it"),
        (["report", "ch3-bs-rl", "--scale", "smoke"], 1, "no runs of 'ch3-bs-rl'"),
        (["report", "ch3-bs-rl", "--format", "pdf"], 2, "--format"),
        (["run", "ch3-bs-rl", "--adaptive", "--seeds", "4"], 1, "--adaptive takes --max-seeds"),
        (["run", "ch3-bs-rl", "--max-seeds", "6"], 1, "go with --adaptive"),
        (["run", "ch3-bs-rl", "--adaptive", "--max-seeds", "0"], 2, "--max-seeds"),
        (["run", "ch3-bs-rl", "--adaptive", "--stage-seeds", "1"], 1, "at least 2 seeds"),
        (
            ["run", "ch3-bs-rl", "--adaptive", "--stage-seeds", "8", "--max-seeds", "4"],
            1,
            "at most --max-seeds",
        ),
        (["report", "ch3-bs-rl", "--from-values", "gone.csv"], 1, "values file not found"),
    ],
)
def test_bad_arguments(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], code: int, needle: str
) -> None:
    runs = tmp_path / "runs"
    assert main(["experiment", *argv, "--runs-dir", str(runs)]) == code
    one_error_line(capsys, needle)
    assert not runs.exists() or not _files(runs)


@pytest.mark.parametrize(
    ("rows", "extra", "needle"),
    [
        ("arm,seed,metric\n", ["--format", "json"], "is not a values table"),
        ("arm,seed,condition,metric,value\nCS,0,,final_best_fitness,1.0\n", ["--format", "json"],
         "line 2: arm 'CS'"),
        ("arm,seed,condition,metric,value\nBS,zero,,final_best_fitness,1.0\n",
         ["--format", "json"], "line 2: not a row of values"),
        ("arm,seed,condition,metric,value\nBS,0,,final_best_fitness,1.0\n", [], "give --out"),
    ],
)  # fmt: skip
def test_bad_values_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], rows: str, extra: list[str], needle: str
) -> None:
    values = tmp_path / "values.csv"
    values.write_text(rows, encoding="utf-8")
    argv = ["experiment", "report", "ch3-bs-rl", "--runs-dir", str(tmp_path / "runs")]
    assert main([*argv, "--from-values", str(values), *extra]) == 1
    one_error_line(capsys, needle)
    assert not (tmp_path / "runs").exists()


def test_file_name_and_scale_must_match(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = str(write_tiny(tmp_path))
    assert main(["experiment", "status", "other", "--file", path, "--scale", "smoke"]) == 1
    one_error_line(capsys, "defines experiment 'tiny', not 'other'")
    assert main(["experiment", "status", "--file", path, "--scale", "thesis"]) == 1
    one_error_line(capsys, "has no scale 'thesis'")


def test_a_file_may_not_take_a_shipped_experiments_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_tiny(tmp_path, TINY_TOML.replace('name = "tiny"', 'name = "ch3-bs-rl"', 1))
    runs = tmp_path / "runs"
    assert main(["experiment", "run", "--file", str(path), "--runs-dir", str(runs)]) == 1
    one_error_line(capsys, "'ch3-bs-rl', as a shipped experiment is named")
    assert not runs.exists()


def test_a_kept_file_that_is_not_an_experiment_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    kept = tmp_path / "experiments" / "mine" / "experiment.toml"
    kept.parent.mkdir(parents=True)
    kept.write_text(TINY_TOML)  # a valid experiment, but named "tiny"
    argv = ["experiment", "status", "mine", "--runs-dir", str(tmp_path), "--scale", "smoke"]
    assert main(argv) == 1
    one_error_line(capsys, str(kept), "defines experiment 'tiny', not 'mine'")
    kept.write_text("name = ")
    assert main(argv) == 1
    one_error_line(capsys, str(kept), "not valid TOML")


def test_bad_experiment_name_in_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = tiny_data()
    data["name"] = "../escape"
    path = tmp_path / "bad.toml"
    path.write_text(to_toml(data))
    assert main(["experiment", "run", "--file", str(path), "--runs-dir", str(tmp_path)]) == 1
    one_error_line(capsys, "'../escape'")
    assert not (tmp_path / "experiments").exists() and not (tmp_path.parent / "escape").exists()


def test_foreign_run_file_is_never_overwritten(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec_path = write_tiny(tmp_path)
    runs = tmp_path / "runs"
    target = Path(plan(load_file(spec_path), "smoke", runs)[1].path)
    train(tiny_config(), target, workers=1)  # another config at an experiment's path
    before = _files(runs)
    argv = ["experiment", "run", "--file", str(spec_path), "--runs-dir", str(runs)]
    assert main(["experiment", "status", *argv[2:], "--scale", "smoke"]) == 0
    assert f"unreadable: {target} holds a run with another config" in capsys.readouterr().out
    assert main([*argv, "--scale", "smoke", "--quiet"]) == 1
    one_error_line(capsys, str(target), "another config")
    assert _files(runs) == before
    assert main(["experiment", "report", *argv[2:], "--scale", "smoke"]) == 1
    one_error_line(capsys, str(target))
    assert _files(runs) == before


def test_condition_stored_with_other_settings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec_path = write_tiny(tmp_path)
    spec = load_file(spec_path)
    runs = tmp_path / "runs"
    task = plan(spec, "smoke", runs)[0]
    train(task.config, task.path, workers=1)
    other = build_config({"implementation": {"steps": 30, "fault_step": 10, "repeats": 1}})
    implement(task.path, other.implementation, name="break-1")
    before = _files(runs)
    argv = ["experiment", "run", "--file", str(spec_path), "--runs-dir", str(runs)]
    assert main([*argv, "--scale", "smoke", "--quiet"]) == 1
    one_error_line(capsys, "'break-1' with other settings")
    assert _files(runs) == before


def test_list_shows_sources_and_costs(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["experiment", "list"]) == 0
    out = capsys.readouterr().out
    assert "ch3-bs-rl" in out and "Fig. 3.6" in out
    assert "small  20 runs × 100 generations × 300 individuals × 1000 steps = 600M" in out
    assert "thesis 20 runs × 1000 generations" in out
    # ch3-bs-rl at thesis: 6G robot-steps + 1.08G trial-steps, priced at the measured rate.
    assert f"trial-steps; about {_core_time((6e9 + 1.08e9) / CORE_STEPS_PER_SECOND)} at" in out


@pytest.mark.parametrize(
    ("seconds", "text"),
    [(0.0649, "0.065 core-seconds"), (59.0, "59 core-seconds"), (60.0, "1 core-minutes"),
     (1390.0, "23 core-minutes"), (3600.0, "1 core-hours"), (553_000.0, "150 core-hours")],
)  # fmt: skip
def test_core_time_in_words(seconds: float, text: str) -> None:
    assert _core_time(seconds) == text


@pytest.mark.slow
def test_run_status_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec_path = str(write_tiny(tmp_path))
    common = ["--file", spec_path, "--runs-dir", str(tmp_path / "runs"), "--scale", "smoke"]
    assert main(["experiment", "status", *common]) == 0
    assert "0/4 runs done, 0/12 generations, 0/12 conditions" in capsys.readouterr().out
    assert main(["experiment", "run", *common, "--workers", "1", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert out.count("final best fitness") == 4 and "break-1" in out and "no-fault" in out
    summary = tmp_path / "runs/experiments/tiny/summary-smoke.h5"
    assert f"summary: {summary}" in out and summary.is_file()
    assert main(["experiment", "status", *common]) == 0
    out = capsys.readouterr().out
    assert "4/4 runs done, 12/12 generations, 12/12 conditions" in out
    assert "RL-seed1" in out and f"summary: {summary}" in out
    # The run kept its file: the experiment is now known by name in that runs dir.
    kept = tmp_path / "runs/experiments/tiny/experiment.toml"
    assert kept.read_text() == TINY_TOML
    by_name = ["tiny", *common[2:]]
    assert main(["experiment", "status", *by_name]) == 0
    assert "tiny at scale smoke: 4/4 runs done" in capsys.readouterr().out
    assert main(["experiment", "report", *by_name, "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["experiment"] == "tiny"
    stamp = summary.stat().st_mtime_ns
    for task in plan(load_file(spec_path), "smoke", tmp_path / "runs"):
        with RunReader(task.path) as run:
            assert run.finished and run.implementation_names() == sorted(
                ["break-1", "fixed-2-3", "no-fault"]
            )
    assert main(["experiment", "run", *common, "--quiet"]) == 0  # nothing left to run
    assert "final best fitness" not in capsys.readouterr().out
    assert main(["experiment", "report", *common, "--out", str(tmp_path / "report")]) == 0
    assert summary.stat().st_mtime_ns >= stamp
    assert f"report: {tmp_path / 'report' / 'index.html'}" in capsys.readouterr().out
    assert (tmp_path / "report" / "values.csv").is_file()
    assert (tmp_path / "runs/experiments/tiny/report-smoke/index.html").is_file()  # from `run`
    assert main(["experiment", "report", *common, "--format", "json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert [c["name"] for c in report["comparisons"]] == ["fitness", "after-1", "BS-fault-hurts"]
    results = read_summary(summary)
    for comparison in report["comparisons"]:  # the report's means are the run files' values
        paired = comparison["condition_b"] is not None  # BS with 2 sensors broken against none
        assert comparison["paired"] == paired and comparison["t_test"]["test"] == (
            "paired t" if paired else "Welch"
        )
        sides = [("a", "BS", comparison["condition"])]
        sides.append(("b", "BS", comparison["condition_b"]) if paired else ("b", "RL", sides[0][2]))
        for side, arm, condition in sides:
            values = results.scalar(comparison["metric"], arm, condition)
            assert comparison[side]["name"] == arm and comparison[side]["n"] == 2
            assert comparison[side]["mean"] == pytest.approx(values.mean(), rel=1e-12)
        assert comparison["verdict"] in VERDICTS
    # The same report again from its values.csv alone (the run files not read)
    table = tmp_path / "report" / "values.csv"
    assert main(["experiment", "report", *common, "--from-values", str(table), "--format",
                 "json"]) == 0  # fmt: skip
    assert json.loads(capsys.readouterr().out)["comparisons"] == report["comparisons"]
