"""The one rule for what a "ruled out" excludes (issue #30), by hand-computed cases."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from app.experiments.margins import margin_of
from app.experiments.results import METRICS, Comparison, ThesisValue
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import load_shipped, parse

REWARD = METRICS["mean_reward"]
DOCS = Path(__file__).resolve().parents[3] / "docs" / "experiments"


def _claim(direction: str = "greater", margin: float | None = None, form: str = "absolute"):
    return Comparison(
        "c", "A", "B", "mean_reward", "x", direction,  # type: ignore[arg-type]
        "Table 2.6", margin=margin, margin_form=form, margin_source="test",  # type: ignore[arg-type]
    )  # fmt: skip


def _printed(a: float, b: float) -> tuple[ThesisValue, ThesisValue]:
    return (
        ThesisValue("A", "mean_reward", "x", a, "Table 2.6"),
        ThesisValue("B", "mean_reward", "x", b, "Table 2.6"),
    )


def test_printed_values_give_the_smaller_of_the_absolute_and_relative_readings() -> None:
    # Δ = 0.47 − 0.40 = 0.07; relative 0.07 / 0.40 = 17.5% of our b 0.2 = 0.035.
    margin = margin_of(_claim(), REWARD, *_printed(0.47, 0.40), mean_b=0.2)
    assert margin.basis == "thesis" and margin.value == pytest.approx(0.035)
    # With our b at 0.6 the relative reading is 0.105 and the absolute one is smaller.
    margin = margin_of(_claim(), REWARD, *_printed(0.47, 0.40), mean_b=0.6)
    assert margin.value == pytest.approx(0.07) and "absolute reading" in margin.text


def test_a_reading_no_run_could_reach_is_dropped() -> None:
    # ch2-training-noise's WN_Train claim: 0.470 against 0.143 (+229%); our b 0.452.
    margin = margin_of(_claim(), REWARD, *_printed(0.470, 0.143), mean_b=0.452)
    assert margin.value == pytest.approx(0.327)  # relative 1.034 would need a reward of 1.49
    assert "relative out of reach" in margin.text
    # With our b at 0.9 neither 0.9 + 0.327 nor 0.9 × 3.29 is a reward per step.
    assert margin_of(_claim(), REWARD, *_printed(0.470, 0.143), mean_b=0.9).value is None


def test_printed_values_against_the_claim_leave_nothing_to_rule_out() -> None:
    # The claim says A > B, but the table prints A below B (0.216 against 0.360).
    margin = margin_of(_claim(margin=0.4, form="relative"), REWARD, *_printed(0.216, 0.36), 0.3)
    assert margin.value is None and "the other way" in margin.text
    # A "less" claim takes the same values the claimed way: |Δ| = 0.144.
    margin = margin_of(_claim("less"), REWARD, *_printed(0.216, 0.36), mean_b=0.3)
    assert margin.value == pytest.approx(0.12)  # relative 0.144 / 0.36 × 0.3 < 0.144


def test_without_printed_values_the_declared_margin_stands_where_reachable() -> None:
    assert margin_of(_claim(margin=0.02), REWARD, None, None, 0.5).value == 0.02
    assert margin_of(_claim(margin=0.02), REWARD, None, None, 0.5).basis == "declared"
    assert margin_of(_claim(margin=0.1, form="relative"), REWARD, None, None, 0.4).value == (
        pytest.approx(0.04)
    )
    assert margin_of(_claim(margin=0.02), REWARD, None, None, 0.99).value is None
    assert margin_of(_claim(), REWARD, None, None, 0.5).basis == "none"


def test_an_absolute_margin_beyond_the_metric_is_refused_when_the_spec_loads() -> None:
    spec = load_shipped("ch3-bs-rl").model_dump(mode="json", exclude_none=True)
    spec["comparisons"][0]["margin"] = 1.5  # a fitness difference of 1.5: no run could reach
    with pytest.raises(ExperimentError, match=r"training-fitness.*no run could reach"):
        parse(spec, "test")


def test_every_committed_ruled_out_excludes_the_printed_difference_the_claimed_way() -> None:
    checked = 0
    for path in DOCS.glob("*/report.json"):
        for c in json.loads(path.read_text())["comparisons"]:
            a, b = c["a"]["thesis"], c["b"]["thesis"]
            if c["verdict"] != "ruled out" or not (a and b) or c["direction"] == "equivalent":
                continue
            delta = a["value"] - b["value"]
            if c["direction"] == "greater":
                assert delta > 0 and c["interval"]["high"] < delta, c["name"]
            else:
                assert delta < 0 and c["interval"]["low"] > delta, c["name"]
            checked += 1
    assert checked >= 10
