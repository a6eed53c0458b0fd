"""Experiment files: the shipped ch3-bs-rl reads as the thesis says, and every bad file fails
with one line naming the problem."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from experiment_fixtures import tiny_data, to_toml

from app.experiments import spec_loading
from app.experiments.results import METRICS
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import load_file, load_shipped, parse, shipped_names


def test_ch3_is_the_thesis_experiment() -> None:
    spec = load_shipped("ch3-bs-rl")
    assert "ch3-bs-rl" in shipped_names()
    assert [a.name for a in spec.arms] == ["BS", "RL"]
    for scale in ("small", "thesis"):
        bs, rl = (spec.run_config(arm, scale, 3) for arm in ("BS", "RL"))
        assert bs.seed == rl.seed == 3  # paired seeds
        assert (
            bs.brain.controller.method,
            bs.brain.controller.sub_nodes,
            bs.brain.controller.n_branch,
        ) == (
            "BS",
            2,
            2,
        )
        assert (rl.brain.controller.method, rl.brain.controller.sub_nodes) == ("RL", 4)
        for run in (bs, rl):
            assert run.brain.controller.fuzzy and run.training.noise_sigma == 50
            assert run.training.population == 300 and run.training.steps == 1000
            assert run.implementation.noise_sigma == 50
        info = spec.conditions_info(scale)
        assert [c.broken_count for c in info] == [0, 1, 2, 3, 4, 5]
        # the no-fault control: the same trials, no sensor breaks
        assert spec.control == info[0].name and info[0].fault_step is None
        assert [c.fault_step for c in info[1:]] == [500] * 5
        for condition in spec.conditions:
            settings = spec.condition_settings(condition, bs, scale)
            assert settings.steps == 3000 and settings.has_fault == (condition.name != spec.control)
            assert settings.broken_sensors == () and settings.fault_mode == "dead"
            assert settings.epsilon == 0.1 and settings.alpha == 0.1
    assert spec.run_config("BS", "small", 0).training.generations == 100
    assert spec.run_config("BS", "thesis", 0).training.generations == 1000
    assert spec.condition_settings(spec.conditions[0], bs, "small").repeats == 30
    assert spec.condition_settings(spec.conditions[0], bs, "thesis").repeats == 300
    assert spec.seed_list("small") == spec.seed_list("thesis") == tuple(range(10))
    assert spec.seed_list("smoke") == (0, 1) and spec.seed_list("smoke", 5) == tuple(range(5))
    claims = {(c.a, c.b, c.metric, c.condition, c.direction) for c in spec.comparisons}
    assert ("BS", "RL", "final_best_fitness", None, "greater") in claims
    for k in range(1, 6):
        assert ("BS", "RL", "mean_reward_after_fault", f"break-{k}", "greater") in claims
        assert ("BS", "RL", "fault_effect", f"break-{k}", "greater") in claims  # recovers better
    assert all(c.metric in METRICS for c in spec.comparisons)
    assert all(c.margin is not None and c.margin_source for c in spec.comparisons)


def test_smoke_scale_sizes_every_condition() -> None:
    spec = load_shipped("ch3-bs-rl")
    run = spec.run_config("RL", "smoke", 1)
    assert run.training.generations == 2 and run.training.population == 12
    for condition in spec.conditions:
        settings = spec.condition_settings(condition, run, "smoke")
        assert settings.steps == 120 and settings.fault_step == 40 and settings.repeats == 1


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    def change(data: dict[str, Any]) -> None:
        *parents, last = path.split(".")
        target: Any = data
        for part in parents:
            target = target[int(part)] if part.isdigit() else target.setdefault(part, {})
        target[last] = value

    return change


def _append(key: str, index: int) -> Callable[[dict[str, Any]], None]:
    return lambda data: data[key].append(dict(data[key][index]))


def _arm_fault_step(data: dict[str, Any]) -> None:
    for scale in data["scales"].values():
        del scale["config"]["implementation"]["fault_step"]
    data["config"]["implementation"]["fault_step"] = 40
    data["arms"][1]["config"]["implementation"] = {"fault_step": 30}


def _shorter_control(data: dict[str, Any]) -> None:
    for scale in data["scales"].values():  # the scales size every condition alike
        del scale["config"]["implementation"]["steps"]
    data["config"]["implementation"]["steps"] = 100
    data["control"] = "no-fault"
    data["conditions"][2]["implementation"] = {"steps": 80}


def _same_metric_b(data: dict[str, Any]) -> None:
    data["comparisons"][2].pop("condition_b")
    data["comparisons"][2]["metric_b"] = data["comparisons"][2]["metric"]


BAD: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    ("unknown arm", _set("comparisons.0.a", "CS"), "unknown arm 'CS'"),
    ("unknown metric", _set("comparisons.0.metric", "speed"), "unknown metric 'speed'"),
    ("curve metric", _set("comparisons.0.metric", "best_fitness_curve"), "is a curve"),
    ("no condition", lambda data: data["comparisons"][1].pop("condition"), "needs a condition"),
    ("training + condition", _set("comparisons.0.condition", "break-1"), "training metric"),
    ("unknown condition", _set("comparisons.1.condition", "break-9"), "unknown condition"),
    ("same arm", _set("comparisons.0.b", "BS"), "with itself; give condition_b"),
    ("condition_b, two arms", _set("comparisons.1.condition_b", "no-fault"), "the same arm"),
    ("condition_b = condition", _set("comparisons.2.condition_b", "fixed-2-3"), "same as a"),
    ("metric_b = metric", _same_metric_b, "same as a"),
    ("metric_b, two arms", _set("comparisons.1.metric_b", "mean_reward"), "the same arm"),
    ("curve metric_b", _set("comparisons.2.metric_b", "reward_per_step"), "is a curve"),
    ("unknown metric_b", _set("comparisons.2.metric_b", "speed"), "unknown metric"),
    ("unknown condition_b", _set("comparisons.2.condition_b", "break-9"), "unknown condition"),
    ("training condition_b", _set("comparisons.2.metric", "final_best_fitness"), "training"),
    ("bad direction", _set("comparisons.0.direction", "bigger"), "direction"),
    ("thesis arm", _set("thesis.0.arm", "XX"), "unknown arm 'XX'"),
    ("thesis metric", _set("thesis.0.metric", "nope"), "unknown metric 'nope'"),
    ("duplicate arm", _append("arms", 0), "duplicate arm name 'BS'"),
    ("duplicate condition", _append("conditions", 1), "duplicate condition name"),
    ("duplicate comparison", _append("comparisons", 0), "duplicate comparison name"),
    ("unknown scale", _set("scales.huge", {"seeds": 1}), "scales.huge"),
    ("unknown key", _set("colour", "red"), "colour: unknown setting"),
    ("unknown preset", _set("preset", "ch9"), "unknown preset 'ch9'"),
    ("path name", _set("name", "../up"), "'../up'"),
    ("arm path name", _set("arms.0.name", "a/b"), "arm name 'a/b'"),
    ("bad arm overlay", _set("arms.1.config.training", {"population": -3}), "population"),
    ("unknown overlay", _set("arms.1.config.controller", {"methd": "RL"}), "methd"),
    ("bad condition", _set("conditions.0.implementation", {"break_count": 9}), "break_count"),
    ("both faults", _set("conditions.0.implementation.broken_sensors", [1]), "not both"),
    ("bad scale value", _set("scales.smoke.config.training.steps", 0), "'smoke'"),
    ("fault after end", _set("scales.small.config.implementation.fault_step", 500), "fault_step"),
    ("zero seeds", _set("seeds", 0), "seeds"),
    ("arms' conditions differ", _arm_fault_step, "the same for every arm"),
    ("no arms", _set("arms", []), "arms"),
    ("margin unexplained", _set("comparisons.0.margin", 0.1), "say where its margin comes from"),
    ("zero margin", _set("comparisons.0.margin", 0.0), "margin"),
    ("margin form", _set("comparisons.0.margin_form", "percent"), "margin_form"),
    ("role", _set("comparisons.0.role", "main"), "role"),
    ("equivalence, no margin", _set("comparisons.0.direction", "equivalent"), "needs a margin"),
    ("unknown control", _set("control", "calm"), "control: unknown condition 'calm'"),
    ("control with a fault", _set("control", "break-1"), "has a fault"),
    ("fault_effect, no control", _set("comparisons.1.metric", "fault_effect"), "needs the"),
    ("control shorter", _shorter_control, "lasts 100 steps, the control 80"),
]


@pytest.mark.parametrize(("change", "needle"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_file_fails_with_one_line(
    tmp_path: Path, change: Callable[[dict[str, Any]], None], needle: str
) -> None:
    data = tiny_data()
    change(data)
    path = tmp_path / "bad.toml"
    path.write_text(to_toml(data), encoding="utf-8")
    with pytest.raises(ExperimentError) as raised:
        load_file(path)
    message = str(raised.value)
    assert "\n" not in message and needle in message, message
    assert str(path) in message or "name" in message or "experiment 'tiny'" in message


def test_good_file_round_trips(tmp_path: Path) -> None:
    path = tmp_path / "tiny.toml"
    path.write_text(to_toml(tiny_data()), encoding="utf-8")
    spec = load_file(path)
    assert spec == parse(tiny_data(), "again")
    with pytest.raises(ExperimentError, match="no scale 'thesis'"):
        spec.scale("thesis")
    assert [c.fault_step for c in spec.conditions_info("smoke")] == [40, 40, None]


def test_margins_roles_and_the_control_reach_the_claims() -> None:
    data = tiny_data()
    data["control"] = "no-fault"
    data["comparisons"][0].update(margin=0.05, margin_form="relative", margin_source="Fig. 3.6")
    data["comparisons"][1].update(metric="fault_effect", role="sanity")
    data["comparisons"].append(
        dict(data["comparisons"][0], name="alike", direction="equivalent", margin=0.5,
             margin_form="absolute", margin_source="declared")
    )  # fmt: skip
    spec = parse(data, "test")
    fitness, after, fault_hurts, alike = spec.comparisons_info()
    assert (fitness.margin, fitness.margin_form, fitness.margin_source) == (
        0.05, "relative", "Fig. 3.6",
    )  # fmt: skip
    assert fitness.margin_for(200.0) == pytest.approx(10.0)
    assert (alike.direction, alike.margin_for(200.0)) == ("equivalent", 0.5)
    assert after.metric == "fault_effect" and after.margin is None
    # role: a question between two arms, a sanity claim within one, unless the file says so
    assert [c.kind for c in (fitness, after, fault_hurts)] == ["question", "sanity", "sanity"]
    assert spec.control == "no-fault"


@pytest.mark.parametrize(("text", "needle"), [(None, "not found"), ("name = [", "not valid TOML")])
def test_unreadable_file(tmp_path: Path, text: str | None, needle: str) -> None:
    path = tmp_path / "x.toml"
    if text is not None:
        path.write_text(text)
    with pytest.raises(ExperimentError, match=needle):
        load_file(path)


def test_unknown_shipped_name() -> None:
    with pytest.raises(ExperimentError, match="no shipped experiment named 'ch9'"):
        load_shipped("ch9")


def test_a_shipped_spec_that_is_not_toml_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "broken.toml").write_text('name = "broken" "a second string"\n')
    monkeypatch.setattr(spec_loading.resources, "files", lambda _package: tmp_path)
    assert shipped_names() == ("broken",)
    with pytest.raises(ExperimentError, match=r"^shipped experiment 'broken' is not valid TOML"):
        load_shipped("broken")
    with pytest.raises(ExperimentError) as raised:
        load_shipped("broken")
    assert "\n" not in str(raised.value) and "(at line 1, column 17)" in str(raised.value)
