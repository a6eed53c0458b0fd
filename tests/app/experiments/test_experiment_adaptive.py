"""`run_adaptive` on an in-process Dask cluster: stages of seeds that stop when the claims are
decided and run only the arms an open claim needs, a rerun that makes no run and decides the
same, and the stages in the summary and in `gnp-lab experiment report --format json`.

The three arms are the same config, so every seed gives every arm the same values: any claim
between them has Δ = 0 exactly. The planted effect is added to the collected values (no
config of this simulator guarantees a large difference on a few seeds of a tiny run).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from experiment_fixtures import copies_toml, in_process_client

from app.cli import main
from app.experiments import adaptive, harvest
from app.experiments.adaptive import Stage, needed_arms, run_adaptive
from app.experiments.results import ExperimentResults
from app.experiments.runner import RunOptions
from app.experiments.spec import ExperimentSpec
from app.experiments.spec_loading import load_file
from app.experiments.summary import read_summary

SCALE = "smoke"
PLANTED = 1000.0  # added to arm X's final best fitness: far beyond any spread of tiny runs
SAME_TOML = copies_toml(
    "same",
    "XYZ",
    """
[[comparisons]]
name = "planted"
a = "X"
b = "Y"
metric = "final_best_fitness"
direction = "greater"
source = "tests"

[[comparisons]]
name = "same"
a = "Y"
b = "Z"
metric = "mean_reward"
condition = "calm"
direction = "greater"
source = "tests"
margin = 0.5
margin_source = "a difference no identical arms reach"

[[comparisons]]
name = "open"
a = "Y"
b = "Z"
metric = "fault_effect"
condition = "break-1"
direction = "greater"
source = "tests"
""",
    control="calm",
)


def planted(results: ExperimentResults) -> ExperimentResults:
    """The results with PLANTED added to arm X's final best fitness."""
    key = ("final_best_fitness", "X", "")
    return dataclasses.replace(
        results, scalars={**results.scalars, key: results.scalars[key] + PLANTED}
    )


@pytest.fixture(scope="module")
def plant() -> Iterator[None]:
    """Every collect of this module's runs (the stages', the CLI's) carries the planted effect."""
    collect = harvest.collect

    def collect_planted(*args: Any, **kwargs: Any) -> ExperimentResults:
        return planted(collect(*args, **kwargs))

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(harvest, "collect", collect_planted)
        patch.setattr(adaptive, "collect", collect_planted)
        yield


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "same.toml"
    path.write_text(SAME_TOML, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    with in_process_client() as c:
        yield c


def adapt(
    spec: ExperimentSpec, runs: Path, client: Any, lines: list[str]
) -> tuple[ExperimentResults, tuple[Stage, ...]]:
    """The experiment run adaptively in stages of 3 seeds up to 6, its lines into `lines`."""
    options = RunOptions(client=client, echo=lines.append)
    return run_adaptive(spec, SCALE, runs, stage_seeds=3, max_seeds=6, options=options)


@pytest.fixture(scope="module")
def adaptive_run(
    plant: None,  # noqa: ARG001 (requested for its patch: a fixture takes no usefixtures mark)
    spec_file: Path,
    client: Any,
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[ExperimentSpec, Path, ExperimentResults, tuple[Stage, ...], list[str]]:
    spec = load_file(spec_file)
    runs = tmp_path_factory.mktemp("runs")
    lines: list[str] = []
    results, stages = adapt(spec, runs, client, lines)
    return spec, runs, results, stages, lines


def run_files(runs: Path) -> dict[str, int]:
    """The run files of the experiment, with their modification times."""
    folder = runs / "experiments" / "same" / SCALE
    return {p.stem: p.stat().st_mtime_ns for p in sorted(folder.glob("*.h5"))}


def test_identical_arms_give_identical_values(adaptive_run: Any) -> None:
    _, _, results, _, _ = adaptive_run
    for (metric, arm, condition), values in results.scalars.items():
        if arm == "Z":
            y = results.scalars[(metric, "Y", condition)]
            np.testing.assert_array_equal(values, y, err_msg=f"{metric} {condition}")
    fitness = results.scalar("final_best_fitness", "Y")[:3] + PLANTED  # as X's, planted
    np.testing.assert_array_equal(results.scalar("final_best_fitness", "X")[:3], fitness)


def test_the_stages_stop_each_claim_once_decided(adaptive_run: Any) -> None:
    spec, runs, results, stages, lines = adaptive_run
    # The planted effect is decided at the first stage; "open" compares identical arms with
    # no margin, so Δ = 0 decides nothing and it runs to the last stage, on Y and Z only.
    assert [s.seeds for s in stages] == [3, 6]
    assert stages[0].arms == ("X", "Y", "Z") and stages[1].arms == ("Y", "Z")
    assert "planted" not in stages[0].open_claims and "open" in stages[1].open_claims
    assert needed_arms(spec, list(stages[0].open_claims)) == stages[1].arms
    assert set(run_files(runs)) == {
        *(f"X-seed{k}" for k in range(3)),
        *(f"{arm}-seed{k}" for arm in "YZ" for k in range(6)),
    }
    assert lines[0] == "stage 1: seeds 0-2 of X, Y, Z"
    assert "stage 2: seeds 3-5 of Y, Z" in lines  # the seeds it adds
    assert results.seeds == tuple(range(6)) and results.looks == (3, 6)
    assert np.isnan(results.scalar("final_best_fitness", "X")[3:]).all()  # never run


def test_identical_arms_are_never_held_nor_reversed(adaptive_run: Any) -> None:
    from app.experiments.report import analyse

    _, _, results, stages, _ = adaptive_run
    verdicts = {c.comparison.name: c.claim for c in analyse(results).comparisons}
    assert verdicts["planted"].verdict == "held" and verdicts["planted"].judged.look == 0
    assert verdicts["planted"].runs == (3, 3)
    same = verdicts["same"]
    # Δ = 0 exactly: accepted as "no difference this large", or still open at the end
    assert same.judged.interval.difference == 0.0
    assert same.verdict == "ruled out" or (same.verdict == "undecided" and same.judged.look == 1)
    assert ("same" in stages[-1].open_claims) == (same.verdict == "undecided")
    assert verdicts["open"].verdict == "undecided" and verdicts["open"].runs == (6, 6)


def test_fault_effect_is_after_the_fault_less_the_control(adaptive_run: Any) -> None:
    _, _, results, _, _ = adaptive_run
    fault_step = next(c.fault_step for c in results.conditions if c.name == "break-1")
    assert fault_step == 20 and results.control == "calm"
    for arm in "YZ":
        calm = results.curve("reward_per_step", arm, "calm")[:, fault_step:].mean(axis=1)
        after = results.scalar("mean_reward_after_fault", arm, "break-1")
        effect = results.scalar("fault_effect", arm, "break-1")
        assert np.isfinite(effect).all()
        np.testing.assert_allclose(effect, after - calm, rtol=0, atol=1e-12)


def test_a_rerun_runs_nothing_and_decides_the_same(adaptive_run: Any, client: Any) -> None:
    spec, runs, results, stages, _ = adaptive_run
    before = run_files(runs)
    lines: list[str] = []
    again, stages_again = adapt(spec, runs, client, lines)
    assert stages_again == stages and run_files(runs) == before
    assert not any(line.startswith("stage") for line in lines)
    assert again.seeds == results.seeds
    for key, values in results.scalars.items():
        np.testing.assert_array_equal(again.scalars[key], values)


def test_the_summary_and_the_json_report_show_the_stages(
    adaptive_run: Any, spec_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, runs, _, stages, _ = adaptive_run
    summary = read_summary(runs / "experiments" / "same" / f"summary-{SCALE}.h5")
    assert summary.looks == (3, 6) and summary.seeds == tuple(range(6))
    common = ["--file", str(spec_file), "--runs-dir", str(runs), "--scale", SCALE]
    assert main(["experiment", "report", *common, "--format", "json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["looks_planned"] == report["looks_made"] == [3, 6]
    first, second = report["stages"]
    assert (first["seeds_per_arm"], first["runs"]) == (3, {"X": 3, "Y": 3, "Z": 3})
    assert (second["seeds_per_arm"], second["runs"]) == (6, {"X": 3, "Y": 6, "Z": 6})
    assert {"name": "planted", "verdict": "held"} in first["decided"]
    assert first["open_after"] == len(stages[0].open_claims)
    assert second["open_after"] == len(stages[1].open_claims)
    by_name = {c["name"]: c for c in report["comparisons"]}
    assert (by_name["planted"]["look"], by_name["planted"]["runs"]) == (1, [3, 3])
    assert by_name["open"]["need"] is not None  # undecided: what more seeds would buy
    # `run --adaptive` again from the command line: nothing to run, the same verdicts
    before = run_files(runs)
    argv = ["experiment", "run", *common, "--adaptive", "--stage-seeds", "3", "--max-seeds", "6"]
    assert main([*argv, "--quiet"]) == 0
    assert "report: " in capsys.readouterr().out and run_files(runs) == before
    assert main(["experiment", "report", *common, "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["comparisons"] == report["comparisons"]
