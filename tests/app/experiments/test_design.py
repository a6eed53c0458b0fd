"""A pre-registered design in the spec: its checks, its seeds, its looks (issue #32)."""

from __future__ import annotations

import copy
from typing import Any

import pytest

from app.experiments.adaptive import stages_of
from app.experiments.spec import ExperimentError
from app.experiments.spec_loading import load_shipped, parse

DECISIVE = load_shipped("ch3-bs-rl-decisive").model_dump(mode="json", exclude_none=True)


def _decisive(**changes: Any) -> dict[str, Any]:
    data = copy.deepcopy(DECISIVE)
    data.update(changes)
    return data


def test_the_design_decides_the_looks_and_refuses_other_stage_sizes() -> None:
    spec = parse(_decisive(), "test")
    assert stages_of(spec, None, None).looks == (25, 50, 75, 100)
    with pytest.raises(ExperimentError, match="pre-registers its looks"):
        stages_of(spec, 10, None)
    plain = load_shipped("ch3-bs-rl")
    assert stages_of(plain, None, None).looks == (10, 20, 30)
    assert stages_of(plain, 5, 12).looks == (5, 10, 12)


def test_fresh_seeds_start_at_first_seed() -> None:
    spec = parse(_decisive(first_seed=500), "test")
    assert spec.seed_list("thesis")[:2] == (500, 501) and len(spec.seed_list("thesis")) == 100
    assert spec.seed_list("smoke", 3) == (500, 501, 502)
    assert spec.run_config("BS", "thesis", 501).seed == 501


def test_a_design_names_at_most_four_primary_claims() -> None:
    data = _decisive()
    for claim in data["comparisons"]:
        claim["family"] = "primary"
    with pytest.raises(
        ExperimentError, match=r"15 primary claims; a decisive experiment names 1 to 4"
    ):
        parse(data, "test")


def test_a_design_declares_every_claims_pairing() -> None:
    data = _decisive()
    del data["comparisons"][0]["paired"]
    with pytest.raises(ExperimentError, match="'before-the-fault' must declare paired"):
        parse(data, "test")


def test_the_last_look_is_the_scales_seed_count() -> None:
    data = _decisive()
    data["scales"]["thesis"]["seeds"] = 80
    with pytest.raises(ExperimentError, match="has 80 seeds; the last look has 100"):
        parse(data, "test")


def test_a_declared_pairing_reaches_the_analysis() -> None:
    spec = parse(_decisive(), "test")
    claims = {c.name: c for c in spec.comparisons_info()}
    assert claims["before-the-fault"].paired is False  # declared unpaired
    assert (
        claims["BS-fault-costs-reward"].paired is True
        and claims["BS-fault-costs-reward"].within_arm
    )
    data = _decisive()
    data["comparisons"][0]["paired"] = True
    assert {c.name: c for c in parse(data, "t").comparisons_info()}["before-the-fault"].paired
