"""statsmodels' Holm and sample size give today's numbers on the committed reports' values.

`holm` (app.experiments.stats) is statsmodels' `multipletests(method="holm")` and
`seeds_for_power` (app.experiments.sequential) its `normal_sample_size_one_tail`; each is
compared here, exactly, with the hand-written version they replaced, on the inputs the
committed reports (docs/experiments/*/report.json) hold. That every committed report
regenerates identical from its values.csv is checked by regenerating them (see
docs/decisions.md).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats as scipy_stats

from app.experiments.sequential import POWER, seeds_for_power
from app.experiments.stats import holm

REPORTS = sorted(
    (Path(__file__).resolve().parents[3] / "docs" / "experiments").glob("*/report.json")
)


def _holm_by_hand(p_values: Sequence[float]) -> np.ndarray:
    """The hand-written Holm that statsmodels replaced."""
    p = np.asarray(p_values, dtype=float)
    adjusted = np.full(p.shape, np.nan)
    tested = np.flatnonzero(~np.isnan(p))
    order = tested[np.argsort(p[tested], kind="stable")]
    m = order.size
    scaled = (m - np.arange(m)) * p[order]
    adjusted[order] = np.minimum(np.maximum.accumulate(scaled), 1.0)
    return adjusted


def _seeds_by_hand(sd: float, effect: float, paired: bool, level: float) -> float:
    """The hand-written sample size that statsmodels replaced."""
    if not math.isfinite(sd) or not math.isfinite(effect):
        return math.nan
    if effect == 0:
        return math.inf
    z = scipy_stats.norm.ppf(1 - level / 2) + scipy_stats.norm.ppf(POWER)
    n = (1 if paired else 2) * (sd * z / effect) ** 2
    return float(max(2, math.ceil(n)))


def _comparisons(path: Path) -> list[dict[str, Any]]:
    return list(json.loads(path.read_text(encoding="utf-8"))["comparisons"])


def test_every_committed_report_is_compared() -> None:
    assert len(REPORTS) >= 10


@pytest.mark.parametrize("path", REPORTS, ids=lambda p: p.parent.name)
def test_holm_gives_the_hand_written_values_on_a_committed_report(path: Path) -> None:
    comparisons = _comparisons(path)
    # Sequentially judged reports keep no fixed-sample p (#44): each claim's two-sided t p is
    # taken from the t and degrees of freedom every report keeps.
    two_sided = [
        min(1.0, 2 * float(scipy_stats.t.sf(abs(c["t_test"]["t"]), c["t_test"]["df"])))
        if c["t_test"].get("t") is not None and c["t_test"].get("df") is not None
        else math.nan
        for c in comparisons
    ]
    primary = [p for p, c in zip(two_sided, comparisons, strict=True) if c["family"] == "primary"]
    for family in (two_sided, primary, [*two_sided, math.nan, two_sided[0]]):  # a tie, a NaN
        np.testing.assert_array_equal(holm(family), _holm_by_hand(family))


def test_holm_gives_the_hand_written_values_at_the_edges() -> None:
    rng = np.random.default_rng(0)
    families: list[list[float]] = [
        [],
        [math.nan],
        [0.5, 0.9, 0.7],
        [0.01, 0.01, 0.01, 0.2],
        [0.0, 1.0, math.nan, 0.0],
        *(list(rng.uniform(0, 0.2, n)) for n in range(1, 40)),
    ]
    for family in families:
        np.testing.assert_array_equal(holm(family), _holm_by_hand(family))


@pytest.mark.parametrize("path", REPORTS, ids=lambda p: p.parent.name)
def test_seeds_for_power_gives_the_hand_written_values_on_a_committed_report(
    path: Path,
) -> None:
    checked = 0
    for c in _comparisons(path):
        level = c["interval"]["family_share"]
        sds = [c["a"]["sd"], c["b"]["sd"]]
        if all(s is not None for s in sds):
            sds.append(math.sqrt((sds[0] ** 2 + sds[1] ** 2) / 2))
        effects = [c["difference"], (c.get("margin") or {}).get("in_units")]
        for sd in (s for s in sds if s is not None):
            for effect in (e for e in effects if e is not None):
                for paired in (False, True):
                    ours = seeds_for_power(sd, effect, paired, level)
                    assert ours == _seeds_by_hand(sd, effect, paired, level), (c["name"], sd)
                    checked += 1
    assert checked


def test_seeds_for_power_gives_the_hand_written_values_over_a_grid() -> None:
    rng = np.random.default_rng(1)
    for sd, effect, level in zip(
        rng.uniform(0.001, 2, 3000), rng.uniform(-0.5, 0.5, 3000), rng.uniform(1e-4, 0.1, 3000),
        strict=True,
    ):  # fmt: skip
        for paired in (False, True):
            assert seeds_for_power(sd, effect, paired, level) == _seeds_by_hand(
                sd, effect, paired, level
            )
    assert math.isnan(seeds_for_power(math.nan, 0.1, False, 0.05))
    assert seeds_for_power(0.1, 0.0, False, 0.05) == math.inf
    assert seeds_for_power(0.0, 0.1, True, 0.05) == 2
