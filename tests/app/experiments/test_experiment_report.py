"""The experiment report: statistics as JSON, and a static page with figures and its data."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread
from scipy import stats as scipy_stats

from app.experiments.figures import mean_and_ci, moving_average, smoothing_window
from app.experiments.report import analyse
from app.experiments.report_json import to_json
from app.experiments.report_page import write_report
from app.experiments.report_text import format_number
from app.experiments.results import (
    CORE_STEPS_PER_SECOND,
    Arm,
    Comparison,
    Condition,
    ExperimentResults,
    ThesisValue,
)
from app.experiments.sequential import ALPHA, seeds_for_power

SEEDS = (11, 12, 13, 14)
STEPS, FAULT_STEP, GENERATIONS = 400, 100, 30
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def synthetic_results(
    seeds: tuple[int, ...] = SEEDS, with_curves: bool = True
) -> ExperimentResults:
    """Two arms where BS clearly beats RL after the fault, and barely in training."""
    rng = np.random.default_rng(3)
    n = len(seeds)
    conditions = tuple(
        Condition(f"break{k}", f"{k} sensor(s) break", STEPS, FAULT_STEP, k, 0.0) for k in (1, 2)
    )
    scalars: dict[tuple[str, str, str], np.ndarray] = {}
    curves: dict[tuple[str, str, str], np.ndarray] = {}
    for arm, skill in (("RL", 0.0), ("BS", 1.0)):
        scalars[("final_best_fitness", arm, "")] = 20 + 0.1 * skill + rng.normal(0, 1, n)
        if with_curves:
            growth = np.log1p(np.arange(GENERATIONS))[None, :]
            curves[("best_fitness_curve", arm, "")] = 4 * growth + rng.normal(0, 0.5, (n, 30))
        for c in conditions:
            after = 0.6 - 0.1 * c.broken_count + 0.05 * skill * c.broken_count
            after_runs = after + rng.normal(0, 0.005, n)
            scalars[("mean_reward_after_fault", arm, c.name)] = after_runs
            scalars[("mean_reward", arm, c.name)] = (0.6 * FAULT_STEP + after_runs * 300) / STEPS
            if with_curves:
                level = np.where(np.arange(STEPS) < FAULT_STEP, 0.6, after)
                curves[("reward_per_step", arm, c.name)] = level + rng.normal(0, 0.1, (n, STEPS))
    comparisons = (
        Comparison("fitness", "BS", "RL", "final_best_fitness", None, "greater", "Fig. 3.6"),
        *(
            Comparison(f"after {c.name}", "BS", "RL", "mean_reward_after_fault", c.name,
                       "greater", "Fig. 3.9")
            for c in conditions
        ),
    )  # fmt: skip
    return ExperimentResults(
        name="ch3-breaking",
        description="Sensors break mid-run: BS against RL.",
        source="Chapter 3",
        scale="smoke",
        arms=(Arm("RL", "Fuzzy GNP-RL"), Arm("BS", "Fuzzy GNP-TSRL (BS)")),
        seeds=seeds,
        conditions=conditions,
        comparisons=comparisons,
        thesis=(ThesisValue("BS", "mean_reward_after_fault", "break1", 0.512, "Table 3.4"),),
        scalars=scalars,
        curves=curves,
    )


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> tuple[ExperimentResults, Path]:
    results = synthetic_results()
    return results, write_report(results, tmp_path_factory.mktemp("report"))


def sections(page: str) -> list[str]:
    """The page's comparison sections, in order."""
    comparisons = page.split("<h2>Comparisons</h2>")[1]
    return [part.split("<h2>")[0] for part in comparisons.split("<h3>")[1:]]


def test_json_means_are_the_means_of_the_runs() -> None:
    results = synthetic_results()
    report = to_json(analyse(results))
    assert report["scale"] == "smoke" and report["seeds"] == list(SEEDS)
    assert report["looks_planned"] == report["looks_made"] == [len(SEEDS)]  # not adaptive
    assert [c["name"] for c in report["comparisons"]] == [c.name for c in results.comparisons]
    for entry, comparison in zip(report["comparisons"], results.comparisons, strict=True):
        for side in ("a", "b"):
            values = results.scalar(comparison.metric, getattr(comparison, side),
                                    comparison.condition)  # fmt: skip
            assert entry[side]["mean"] == pytest.approx(np.mean(values))
            assert entry[side]["sd"] == pytest.approx(np.std(values, ddof=1))
            assert entry[side]["n"] == len(SEEDS) and entry[side]["dropped"] == 0
        a_mean, b_mean = entry["a"]["mean"], entry["b"]["mean"]
        assert entry["difference"] == pytest.approx(a_mean - b_mean)
        interval = entry["interval"]
        assert interval["low"] < entry["difference"] < interval["high"]
        assert entry["holm_p"] >= entry["t_test"]["p"]
        assert (entry["runs"], entry["look"], entry["kind"]) == ([4, 4], 1, "question")
        assert entry["margin"] is None  # none declared
    after = report["comparisons"][1:]
    assert [c["verdict"] for c in after] == ["held", "held"]  # 0.05 and 0.1 apart, sd 0.005
    assert all(c["need"] is None for c in after)  # decided: nothing more needed
    assert after[0]["a"]["thesis"] == {"value": 0.512, "source": "Table 3.4"}
    assert after[0]["b"]["thesis"] is None and after[1]["a"]["thesis"] is None
    json.dumps(report, allow_nan=False)  # valid JSON, no NaN


def test_page_shows_each_comparisons_verdict_and_json_numbers(
    written: tuple[ExperimentResults, Path],
) -> None:
    _, index = written
    page = index.read_text()
    report = json.loads((index.parent / "report.json").read_text())
    assert "smoke" in page and "unit of analysis" in page and "the run (seed)" in page
    assert ", ".join(map(str, SEEDS)) in page
    for section, entry in zip(sections(page), report["comparisons"], strict=True):
        assert section.startswith(entry["name"])
        assert f'class="verdict {entry["verdict"].replace(" ", "-")}">{entry["verdict"]}' in section
        shown = [
            entry["a"]["mean"], entry["a"]["sd"], entry["b"]["mean"], entry["b"]["sd"],
            entry["difference"], entry["interval"]["low"], entry["interval"]["high"],
            entry["t_test"]["p"], entry["rank_test"]["p"],
            entry["holm_p"], entry["prob_improvement"], entry["hedges_g"],
        ]  # fmt: skip
        for number in shown:
            assert format_number(number) in section
    thesis_section = sections(page)[1]
    assert "0.512 (Table 3.4)" in thesis_section


def test_every_figure_on_the_page_is_a_real_png(written: tuple[ExperimentResults, Path]) -> None:
    _, index = written
    images = re.findall(r'<img src="([^"]+)"', index.read_text())
    # fitness, 2 reward curves, the fault sweep, a runs plot per comparison
    assert len(images) == 1 + 2 + 1 + 3
    assert {"fitness.png", "fault.png"} <= set(images)
    for name in images:
        path = index.parent / name
        assert path.read_bytes()[:8] == PNG_MAGIC
        pixels = imread(path)
        assert pixels.shape[0] > 200 and pixels.shape[1] > 300
        assert np.ptp(pixels[..., :3]) > 0.5  # something drawn, not a blank canvas


def test_values_csv_round_trips(written: tuple[ExperimentResults, Path]) -> None:
    results, index = written
    with (index.parent / "values.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["arm", "seed", "condition", "metric", "value"]
    assert len(rows) == len(SEEDS) * len(results.scalars)
    read: dict[tuple[str, str, str], dict[int, float]] = {}
    for row in rows:
        key = (row["metric"], row["arm"], row["condition"])
        read.setdefault(key, {})[int(row["seed"])] = float(row["value"])
    assert read.keys() == results.scalars.keys()
    for key, values in results.scalars.items():
        assert [read[key][seed] for seed in SEEDS] == list(values)  # exact, not approximate


def test_unfinished_runs_are_counted_in_json_and_page(tmp_path: Path) -> None:
    results = synthetic_results()
    rl_after = results.scalars[("mean_reward_after_fault", "RL", "break1")].copy()
    rl_after[[0, 2]] = np.nan
    scalars = {**results.scalars, ("mean_reward_after_fault", "RL", "break1"): rl_after}
    results = dataclasses.replace(results, scalars=scalars)
    index = write_report(results, tmp_path)
    entry = json.loads((tmp_path / "report.json").read_text())["comparisons"][1]
    assert (entry["b"]["n"], entry["b"]["dropped"]) == (2, 2)
    assert entry["b"]["mean"] == pytest.approx(np.nanmean(rl_after))
    assert "2 unfinished run(s) of RL dropped" in entry["notes"]
    assert "2 unfinished run(s) of RL dropped" in sections(index.read_text())[1]
    with (tmp_path / "values.csv").open(newline="") as handle:
        nan_rows = [r for r in csv.DictReader(handle) if math.isnan(float(r["value"]))]
    assert {(r["arm"], r["seed"], r["condition"]) for r in nan_rows} == {
        ("RL", "11", "break1"),
        ("RL", "13", "break1"),
    }


def test_a_single_seed_reports_without_tests_or_bands(tmp_path: Path) -> None:
    index = write_report(synthetic_results(seeds=(5,)), tmp_path)
    report = json.loads((tmp_path / "report.json").read_text())
    assert all(c["verdict"] == "undecided" for c in report["comparisons"])
    assert all(c["t_test"]["p"] is None and c["a"]["sd"] is None for c in report["comparisons"])
    assert all(c["interval"]["low"] is None for c in report["comparisons"])
    # no spread to price seeds by
    assert all(c["need"]["seeds_per_arm_at_our_effect"] is None for c in report["comparisons"])
    for name in re.findall(r'<img src="([^"]+)"', index.read_text()):
        assert (tmp_path / name).read_bytes()[:8] == PNG_MAGIC


def test_missing_curves_leave_out_their_figures(tmp_path: Path) -> None:
    index = write_report(synthetic_results(with_curves=False), tmp_path)
    images = re.findall(r'<img src="([^"]+)"', index.read_text())
    assert "fitness.png" not in images and not any(i.startswith("reward-") for i in images)
    assert "fault.png" in images  # drawn from scalars, not curves
    assert not (tmp_path / "fitness.png").exists()


def test_the_verdicts_interval_is_welchs_at_the_claims_holm_share() -> None:
    results = synthetic_results()
    report = analyse(results)
    fitness, after_1, after_2 = report.comparisons
    # both reward claims are held at α/3; fitness (0.1 apart, sd 1) then stands alone at α
    assert [c.claim.verdict for c in report.comparisons] == ["undecided", "held", "held"]
    assert after_1.claim.judged.family_level == pytest.approx(ALPHA / 3)
    assert after_2.claim.judged.family_level == pytest.approx(ALPHA / 3)
    assert fitness.claim.judged.family_level == pytest.approx(ALPHA)
    bs, rl = (results.scalar("final_best_fitness", arm) for arm in ("BS", "RL"))
    welch = scipy_stats.ttest_ind(bs, rl, equal_var=False).confidence_interval(1 - ALPHA)
    iv = fitness.claim.judged.interval
    assert (iv.low, iv.high) == (pytest.approx(welch.low), pytest.approx(welch.high))
    entry = to_json(report)["comparisons"][0]
    assert entry["interval"]["level"] == pytest.approx(1 - ALPHA)
    assert entry["interval"]["family_share"] == pytest.approx(ALPHA)
    assert to_json(analyse(results)) == to_json(report)  # no resampling: the same every time


def test_an_undecided_claim_says_the_seeds_and_core_hours_it_needs() -> None:
    steps = 2.3e6  # simulated steps per run
    base = synthetic_results()
    key = ("final_best_fitness", "BS", ""), ("final_best_fitness", "RL", "")
    # A fitness lies in 0..1 (a margin must be reachable from b's mean): scale the values into it.
    scale = 2 * max(float(np.nanmax(base.scalars[k])) for k in key)
    results = dataclasses.replace(
        base,
        steps_per_run=steps,
        scalars={**base.scalars, **{k: base.scalars[k] / scale for k in key}},
        comparisons=(
            Comparison("fitness", "BS", "RL", "final_best_fitness", None, "greater", "Fig. 3.6",
                       margin=0.05, margin_form="relative", margin_source="test"),
        ),
    )  # fmt: skip
    (claim,) = analyse(results).comparisons
    judged = claim.claim.judged
    assert judged.verdict == "undecided" and judged.family_level == ALPHA
    rl = results.scalar("final_best_fitness", "RL")
    assert claim.claim.margin == pytest.approx(0.05 * rl.mean())  # 5% of b's mean
    sd = judged.interval.sd
    assert sd == pytest.approx(
        math.sqrt((results.scalar("final_best_fitness", "BS").var(ddof=1) + rl.var(ddof=1)) / 2)
    )  # pooled, equal n
    need = claim.claim.need
    assert need is not None
    at_thesis = seeds_for_power(sd, 0.05 * rl.mean(), False, ALPHA)
    at_ours = seeds_for_power(sd, abs(judged.interval.difference), False, ALPHA)
    assert (need.seeds_at_thesis, need.seeds_at_ours) == (at_thesis, at_ours)
    hours = at_thesis * 2 * steps / CORE_STEPS_PER_SECOND / 3600  # both arms' runs
    assert need.core_hours_at_thesis == pytest.approx(hours)
    entry = to_json(analyse(results))["comparisons"][0]
    assert entry["margin"] == {
        "value": 0.05,
        "form": "relative",
        "source": "test",
        "in_units": pytest.approx(0.05 * rl.mean()),
        "basis": "declared",
        "rule": "0.05 of b's mean; test",
    }
    assert entry["need"]["seeds_per_arm_at_thesis_effect"] == at_thesis
    assert entry["need"]["core_hours_at_thesis_effect"] == pytest.approx(hours)


def test_a_margin_below_the_interval_is_ruled_out() -> None:
    # the reward claims lie 0.05 and 0.1 apart (sd 0.005): "less" with margin 0.2 is excluded
    results = synthetic_results()
    ruled = [
        Comparison(f"below {c}", "BS", "RL", "mean_reward_after_fault", c, "less", "test",
                   margin=0.2, margin_source="test")
        for c in ("break1", "break2")
    ]  # fmt: skip
    equal = Comparison("same", "BS", "RL", "mean_reward_after_fault", "break1", "equivalent",
                       "test", margin=0.2, margin_source="test")  # fmt: skip
    apart = Comparison("apart", "BS", "RL", "mean_reward_after_fault", "break2", "equivalent",
                       "test", margin=0.02, margin_source="test")  # fmt: skip
    results = dataclasses.replace(results, comparisons=(*ruled, equal, apart))
    report = to_json(analyse(results))
    assert [c["verdict"] for c in report["comparisons"]] == [
        "reversed",  # the interval lies above 0, the claim says below
        "reversed",
        "held",  # 0.05 apart lies within ±0.2
        "ruled out",  # 0.1 apart lies beyond ±0.02
    ]


def test_the_looks_of_an_adaptive_run_decide_claims_early() -> None:
    seeds = tuple(range(6))
    results = dataclasses.replace(synthetic_results(seeds), looks=(3, 6))
    report = to_json(analyse(results))
    assert report["looks_planned"] == report["looks_made"] == [3, 6]
    fitness, *after = report["comparisons"]
    # 0.05 and 0.1 apart with sd 0.005: decided on the first three runs of each arm
    assert [(c["verdict"], c["look"], c["runs"]) for c in after] == [("held", 1, [3, 3])] * 2
    assert (fitness["verdict"], fitness["look"], fitness["runs"]) == ("undecided", 2, [6, 6])
    first, second = report["stages"]
    assert (first["seeds_per_arm"], first["runs"]) == (3, {"RL": 3, "BS": 3})
    assert {d["name"] for d in first["decided"]} == {"after break1", "after break2"}
    assert (first["open_after"], second["open_after"], second["decided"]) == (1, 1, [])
    # results of the first five seeds have made the first look only
    partial = dataclasses.replace(results, seeds=seeds[:5], scalars={
        k: v[:5] for k, v in results.scalars.items()})  # fmt: skip
    assert to_json(analyse(partial))["looks_made"] == [3]


def test_the_page_says_how_many_of_its_looks_an_adaptive_run_made(tmp_path: Path) -> None:
    # an adaptive run stopped between looks: five seeds made the first look (3) of two (3, 6)
    cut = dataclasses.replace(synthetic_results(tuple(range(5))), looks=(3, 6))
    page = write_report(cut, tmp_path / "cut").read_text()
    assert "<td>adaptive: 1 of 2 looks made; planned at 3, 6 seeds per arm</td>" in page
    plain = write_report(synthetic_results(), tmp_path / "plain").read_text()
    assert f"<td>one look at {len(SEEDS)} seeds per arm (not adaptive)</td>" in plain


def test_the_page_counts_the_runs_each_arm_finished(tmp_path: Path) -> None:
    # RL stopped after 2 seeds (nothing beyond); BS's first run has one condition unfinished
    # (its mean reward) and is not counted; a missing value of another metric does not matter
    results = synthetic_results()
    scalars = {key: values.copy() for key, values in results.scalars.items()}
    for (_, arm, _), values in scalars.items():
        if arm == "RL":
            values[2:] = np.nan
    scalars[("mean_reward", "BS", "break1")][0] = np.nan
    scalars[("mean_reward_after_fault", "BS", "break2")][1] = np.nan
    stopped = dataclasses.replace(results, scalars=scalars)
    page = write_report(stopped, tmp_path / "stopped").read_text()
    assert f"(runs: RL 2, BS {len(SEEDS) - 1})</td>" in page
    plain = write_report(results, tmp_path / "plain").read_text()
    assert f"({len(SEEDS)} runs per arm)</td>" in plain


def test_a_run_is_finished_when_trained_and_every_condition_is_implemented() -> None:
    results = synthetic_results()
    scalars = {key: values.copy() for key, values in results.scalars.items()}
    scalars[("final_best_fitness", "BS", "")][0] = np.nan  # not trained
    scalars[("mean_reward", "BS", "break2")][2] = np.nan  # one condition not implemented
    scalars[("mean_reward_after_fault", "BS", "break1")][3] = np.nan  # not what finishes a run
    robot = dataclasses.replace(results, scalars=scalars)
    expected = [True] * len(SEEDS)
    expected[0] = expected[2] = False
    assert robot.finished("BS").tolist() == expected
    assert robot.finished("RL").all()
    # A task run (no conditions) is finished when tested; its training return alone is not.
    returns = np.array([10.0, np.nan, 30.0])
    task = dataclasses.replace(
        results,
        seeds=(0, 1, 2),
        conditions=(),
        scalars={
            ("final_best_return", "GNP", ""): np.array([1.0, 2.0, 3.0]),
            ("test_return", "GNP", ""): returns,
        },
    )
    assert task.finished("GNP").tolist() == [True, False, True]
    assert not task.finished("nobody").any()  # values these results lack: unfinished


def test_fault_figure_needs_two_broken_counts(tmp_path: Path) -> None:
    results = synthetic_results()
    one_condition = dataclasses.replace(
        results, conditions=results.conditions[:1], comparisons=results.comparisons[:2]
    )
    index = write_report(one_condition, tmp_path)
    assert "fault.png" not in index.read_text() and not (tmp_path / "fault.png").exists()
    assert (tmp_path / "reward-0-break1.png").exists()


def test_mean_and_ci_is_a_t_interval_over_finite_runs() -> None:
    samples = np.array([[1.0, 7.0, 5.0], [2.0, np.nan, 5.0], [3.0, np.nan, np.nan]])
    mean, half_width, n = mean_and_ci(samples)
    # df = 2: F(t) = 1/2 + t / (2√(2 + t²)) = 0.975 ⇔ t² = 2·0.95² / (1 − 0.95²)
    t_975 = math.sqrt(2 * 0.95**2 / (1 - 0.95**2))  # ≈ 4.303
    assert list(n) == [3, 1, 2]
    assert mean == pytest.approx([2.0, 7.0, 5.0])
    assert half_width[0] == pytest.approx(t_975 * 1.0 / math.sqrt(3))  # sd = 1
    assert math.isnan(half_width[1])  # one run: no interval
    assert half_width[2] == 0.0  # two equal runs


def test_moving_average_is_centred_over_the_window() -> None:
    smoothed = moving_average(np.array([[1.0, 2.0, 3.0, 6.0]]), 2)
    assert smoothed == pytest.approx(np.array([[1.5, 2.5, 4.5]]))
    assert smoothing_window(3000) == 50 and smoothing_window(200) == 20


def test_the_thesis_numbers_sit_beside_ours(
    written: tuple[ExperimentResults, Path],
) -> None:
    results, index = written
    (entry,) = json.loads((index.parent / "report.json").read_text())["thesis"]
    ours = results.scalar("mean_reward_after_fault", "BS", "break1")
    assert (entry["arm"], entry["value"], entry["source"]) == ("BS", 0.512, "Table 3.4")
    assert entry["ours"]["mean"] == pytest.approx(np.mean(ours)) and entry["ours"]["n"] == 4
    table = index.read_text().split("The thesis's numbers beside ours")[1]
    assert "0.512 (Table 3.4)" in table and format_number(entry["ours"]["mean"]) in table


def test_one_arm_across_two_conditions_is_tested_paired(tmp_path: Path) -> None:
    results = synthetic_results()
    sweep = Comparison(
        "BS fault sweep", "BS", "BS", "mean_reward_after_fault", "break1", "greater",
        "Fig. 3.9", condition_b="break2",
    )  # fmt: skip
    results = dataclasses.replace(results, comparisons=(*results.comparisons, sweep))
    index = write_report(results, tmp_path)
    entry = json.loads((tmp_path / "report.json").read_text())["comparisons"][-1]
    one, two = (results.scalar("mean_reward_after_fault", "BS", c) for c in ("break1", "break2"))
    assert entry["paired"] and entry["condition_b"] == "break2"
    assert entry["a"]["mean"] == pytest.approx(one.mean())
    assert entry["b"]["mean"] == pytest.approx(two.mean())
    assert entry["t_test"]["test"] == "paired t" and entry["t_test"]["df"] == len(SEEDS) - 1
    assert entry["rank_test"]["test"] == "Wilcoxon signed-rank"
    d = one - two
    assert entry["t_test"]["t"] == pytest.approx(d.mean() / (d.std(ddof=1) / np.sqrt(d.size)))
    assert entry["claim"] == (
        "Fuzzy GNP-TSRL (BS) has a higher mean reward per step after the fault in "
        "1 sensor(s) break than in 2 sensor(s) break"
    )
    section = sections(index.read_text())[-1]
    assert "paired t t (df)" in section and "Wilcoxon signed-rank W+" in section
    assert "Fuzzy GNP-TSRL (BS), 2 sensor(s) break" in section
    assert (tmp_path / "runs-3-BS-fault-sweep.png").read_bytes()[:8] == PNG_MAGIC


def test_one_arm_on_two_metrics_is_tested_paired(tmp_path: Path) -> None:
    results = synthetic_results()
    fault_hurts = Comparison(
        "RL fault hurts", "RL", "RL", "mean_reward_after_fault", "break2", "less", "Fig. 5.6",
        metric_b="mean_reward",
    )  # fmt: skip
    results = dataclasses.replace(results, comparisons=(fault_hurts,))
    report = to_json(analyse(results))
    (entry,) = report["comparisons"]
    after = results.scalar("mean_reward_after_fault", "RL", "break2")
    whole = results.scalar("mean_reward", "RL", "break2")
    assert entry["paired"] and entry["metric_b"] == "mean_reward"
    assert entry["sides"] == ["mean_reward_after_fault", "mean_reward"]
    assert (entry["a"]["mean"], entry["b"]["mean"]) == (
        pytest.approx(after.mean()),
        pytest.approx(whole.mean()),
    )
    d = after - whole
    assert entry["t_test"]["t"] == pytest.approx(d.mean() / (d.std(ddof=1) / np.sqrt(d.size)))
    assert entry["claim"] == (
        "Fuzzy GNP-RL has a lower mean reward per step after the fault in 2 sensor(s) break "
        "than mean reward per step"
    )
    write_report(results, tmp_path)
    assert "Fuzzy GNP-RL, mean reward per step</td>" in (tmp_path / "index.html").read_text()


def test_a_new_report_replaces_the_figures_of_an_earlier_one(tmp_path: Path) -> None:
    results = synthetic_results()
    write_report(results, tmp_path)
    (tmp_path / "runs-9-a-claim-since-removed.png").write_bytes(PNG_MAGIC)
    (tmp_path / "notes.png").write_bytes(PNG_MAGIC)  # not a report figure: kept
    one_claim = dataclasses.replace(results, comparisons=results.comparisons[:1])
    index = write_report(one_claim, tmp_path)
    shown = set(re.findall(r'<img src="([^"]+)"', index.read_text()))
    assert {p.name for p in tmp_path.glob("*.png")} == shown | {"notes.png"}
