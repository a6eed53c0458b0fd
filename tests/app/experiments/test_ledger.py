"""A committed report's ledger: its runs count as finished on a machine without their files."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from experiment_fixtures import in_process_client, tiny_data, to_toml, write_tiny

from app.experiments import ledger
from app.experiments.report_page import write_report
from app.experiments.runner import RunOptions, run_experiment
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import parse


@pytest.fixture(scope="module")
def client() -> Any:
    with in_process_client() as c:
        yield c


def _committed(tmp_path: Path, client: Any) -> tuple[Any, Path]:
    """The tiny experiment's first 2 seeds run on 'machine 1' and committed as a report."""
    spec = parse(tiny_data(), "tiny")
    results = run_experiment(spec, "smoke", tmp_path / "machine-1", seeds=2,
                             options=RunOptions(client=client, quiet=True))  # fmt: skip
    docs = tmp_path / "docs" / "tiny-smoke"
    write_report(results, docs)
    ledger.write(spec, "smoke", results, docs)
    return spec, docs


@pytest.mark.slow
def test_a_fresh_machine_continues_from_the_ledger_without_rerunning(
    tmp_path: Path, client: Any
) -> None:
    spec, docs = _committed(tmp_path, client)
    held = ledger.load(spec, "smoke", docs)
    assert held.runs == {"BS-seed0", "BS-seed1", "RL-seed0", "RL-seed1"}
    fresh = tmp_path / "machine-2"  # no run file of the committed seeds
    options = RunOptions(client=client, quiet=True, ledger=held)
    results = run_experiment(spec, "smoke", fresh, seeds=3, options=options)
    made = sorted(p.name for p in (fresh / "experiments" / "tiny" / "smoke").glob("*.h5"))
    assert made == ["BS-seed2.h5", "RL-seed2.h5"]  # only the new seed ran
    for key, values in held.values.scalars.items():
        assert np.array_equal(results.scalars[key][:2], values, equal_nan=True), key
    assert np.isfinite(results.scalars[("final_best_fitness", "BS", "")]).all()


@pytest.mark.slow
def test_a_ledger_of_another_config_or_engine_is_refused_in_one_line(
    tmp_path: Path, client: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    spec, docs = _committed(tmp_path, client)
    changed = tiny_data()
    changed["arms"][0]["config"]["controller"]["n_branch"] = 3  # the spec changed since
    with pytest.raises(ExperimentError, match=r"run BS-seed0 was made with another config"):
        ledger.load(parse(changed, "tiny"), "smoke", docs)
    monkeypatch.setattr(ledger, "ENGINE_BITS", ledger.ENGINE_BITS + 1)
    with pytest.raises(ExperimentError, match="engine bits"):
        ledger.load(spec, "smoke", docs)
    # From the command line: one line, non-zero, nothing run.
    monkeypatch.undo()
    spec_file = write_tiny(tmp_path, to_toml(changed))
    done = subprocess.run(
        [sys.executable, "-m", "app.cli", "experiment", "run", "--file", str(spec_file),
         "--scale", "smoke", "--seeds", "2", "--ledger", str(docs),
         "--runs-dir", str(tmp_path / "machine-3")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode != 0
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith("gnp-lab: error:") and "another config" in line
    assert not (tmp_path / "machine-3" / "experiments" / "tiny" / "smoke").exists()


def test_a_setting_added_at_its_default_keeps_a_runs_identity() -> None:
    from app.experiments.planning import plan
    from app.experiments.spec_loading import load_shipped

    task = plan(load_shipped("ch3-bs-rl-decisive"), "thesis", "", 1)[0]
    old = json.loads(task.config_json)
    del old["training"]["noise_stream"]  # as a config written before the setting existed
    before = dataclasses.replace(task, config_json=json.dumps(old))
    assert ledger.fingerprint(before) == ledger.fingerprint(task)
    old["training"]["noise_stream"] = "ziggurat-v1"  # another value: another run
    other = dataclasses.replace(task, config_json=json.dumps(old))
    assert ledger.fingerprint(other) != ledger.fingerprint(task)


@pytest.mark.parametrize("folder", sorted(p.parent.name for p in ledger.DOCS.glob("*/ledger.json")))
def test_every_committed_ledger_loads_on_this_checkout(folder: str) -> None:
    from app.experiments.spec_loading import load_shipped

    name, scale = folder.rsplit("-", 1)
    held = ledger.load(load_shipped(name), scale, ledger.DOCS / folder)
    assert held.runs  # its runs count as finished here: the spec and the bits are the same


@pytest.mark.parametrize(
    ("ledger_text", "problem"), [("[" * 100_000, "nested 100000 deep"), ("{", "is not JSON")]
)
def test_a_hostile_ledger_is_refused_in_one_line(
    tmp_path: Path, ledger_text: str, problem: str
) -> None:
    (tmp_path / ledger.FILE).write_text(ledger_text)
    with pytest.raises(ExperimentError, match=f"no readable ledger in .*{problem}"):
        ledger.load(parse(tiny_data(), "tiny"), "smoke", tmp_path)
