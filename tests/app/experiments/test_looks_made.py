"""A pre-registered design between its looks: a report judges only the looks made, and carries
every finished run (a stage still running included) in its values and ledger, so a fresh
machine continues the stage without rerunning them."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from experiment_fixtures import copies_toml, in_process_client

from app.cli import main
from app.experiments import harvest, ledger, looks_made
from app.experiments.adaptive import run_adaptive
from app.experiments.runner import RunOptions, run_experiment
from app.experiments.spec import ExperimentSpec
from app.experiments.spec_loading import load_file
from app.experiments.values import write_values_csv

SCALE = "smoke"
DESIGNED = copies_toml(
    "designed",
    "XY",
    """
[design]
looks = [2, 3]
max_primary = 4
core_hours = 1.0
power = "a test design"

[[comparisons]]
name = "calm"
a = "X"
b = "Y"
metric = "mean_reward"
condition = "calm"
direction = "greater"
source = "tests"
family = "primary"
paired = true
margin = 0.5
margin_source = "a difference no identical arms reach"
""",
)


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    with in_process_client() as c:
        yield c


def _spec(tmp_path: Path) -> tuple[ExperimentSpec, Path]:
    path = tmp_path / "designed.toml"
    path.write_text(DESIGNED, encoding="utf-8")
    return load_file(path), path


def _report(spec_file: Path, runs: Path, out: Path, *more: str) -> None:
    argv = ["experiment", "report", "--file", str(spec_file), "--scale", SCALE]
    assert main([*argv, "--runs-dir", str(runs), "--out", str(out), *more]) == 0


def _runs(folder: Path) -> list[str]:
    return sorted(p.stem for p in (folder / "experiments" / "designed" / SCALE).glob("*.h5"))


@pytest.mark.slow
def test_before_the_first_look_a_report_carries_the_runs_and_judges_nothing(
    tmp_path: Path, client: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    spec, spec_file = _spec(tmp_path)
    machine_1 = tmp_path / "machine-1"
    # Half of stage 1 (seed 0 of the 2 the first look needs), then the machine is gone.
    run_experiment(spec, SCALE, machine_1, seeds=1, options=RunOptions(client=client, quiet=True))
    docs = tmp_path / "docs" / "designed-smoke"
    _report(spec_file, machine_1, docs)
    assert "no look made yet" in capsys.readouterr().out
    assert not (docs / "report.json").exists()  # no verdict before the first look
    assert "No look made yet, so no verdict" in (docs / "index.html").read_text()
    held = ledger.load(spec, SCALE, docs)
    assert held.runs == {"X-seed0", "Y-seed0"}

    # A fresh machine continues stage 1 from the committed folder: seed 0 is not run again.
    machine_2 = tmp_path / "machine-2"
    options = RunOptions(client=client, quiet=True, ledger=held)
    results, _ = run_adaptive(spec, SCALE, machine_2, options=options)
    assert "X-seed0" not in _runs(machine_2) and "X-seed1" in _runs(machine_2)
    for key, values in held.values.scalars.items():
        assert np.array_equal(results.scalars[key][:1], values[:1], equal_nan=True), key

    # After the looks, the report judges them; written again from its values, the same page.
    _report(spec_file, machine_2, docs, "--ledger", str(docs))
    report = json.loads((docs / "report.json").read_text())
    assert report["looks_made"] and report["looks_made"][-1] == len(results.seeds)
    again = tmp_path / "again"
    _report(spec_file, machine_2, again, "--from-values", str(docs / "values.csv"))
    assert json.loads((again / "report.json").read_text()) == report


def test_a_report_judges_the_looks_made_and_carries_the_stage_in_progress(
    tmp_path: Path,
) -> None:
    spec, _ = _spec(tmp_path)
    assert spec.design is not None
    template = harvest.collect(spec, SCALE, tmp_path / "empty", 3, spec.design.looks)
    assert template.seeds == (0, 1, 2)  # a stage in progress: seed 2 beyond the look at 2
    values = tmp_path / "docs" / "values.csv"
    values.parent.mkdir()
    write_values_csv(template, values)
    (values.parent / "report.json").write_text(json.dumps({"looks_made": [2]}))
    judged = looks_made.judged_from_values(template, values)
    assert judged is not None and judged.seeds == (0, 1)
    assert all(v.shape[0] == 2 for v in judged.scalars.values())
    (values.parent / "report.json").write_text(json.dumps({"looks_made": []}))
    assert looks_made.judged_from_values(template, values) is None
