"""Estimates corrected for stopping (app.experiments.estimates), against the normal theory and
against a simulated group-sequential design."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from app.experiments.estimates import median_unbiased, stopping
from app.experiments.sequential import ClaimData, Design, judge


def test_at_the_first_look_the_stagewise_estimate_is_the_observed_one() -> None:
    stagewise, conditional = median_unbiased(0.3, [0.1], [], [], grid=201)
    assert stagewise == pytest.approx(0.3, abs=1e-8)
    assert conditional == pytest.approx(0.3, abs=1e-8)  # the last look: given it was reached


def test_two_looks_agree_with_the_bivariate_normal() -> None:
    """P(an outcome at least the observed one) at the stagewise estimate is ½, computed
    independently from the bivariate normal of (Z₁, Z₂)."""
    se, lower, upper, estimate = [0.2, 0.1], [-2.8], [2.8], 0.31
    stagewise, _ = median_unbiased(estimate, se, lower, upper)
    i1, i2 = 1 / se[0] ** 2, 1 / se[1] ** 2
    mean = [stagewise * math.sqrt(i1), stagewise * math.sqrt(i2)]
    rho = math.sqrt(i1 / i2)
    z2 = estimate / se[1]
    # P(Z₁ ≥ b) + P(a < Z₁ < b, Z₂ ≥ z): the second from the cdf of (Z₁, −Z₂).
    upper_stop = stats.norm.sf(upper[0] - mean[0])
    flipped = stats.multivariate_normal([mean[0], -mean[1]], [[1, -rho], [-rho, 1]])
    between = flipped.cdf([upper[0], -z2]) - flipped.cdf([lower[0], -z2])
    assert upper_stop + between == pytest.approx(0.5, abs=2e-4)


def _design_run(
    delta: float, rng: np.random.Generator, design: Design
) -> tuple[int, float, float, float]:
    """One experiment of the design under a true Δ: (stopping look, Δ̂ there, stagewise and
    conditional estimates), the looks judged one after another as `run --adaptive` does."""
    n = design.looks[-1]
    a, b = rng.normal(delta, 1.0, n), rng.normal(0.0, 1.0, n)
    looks = [ClaimData(a[:k], b[:k], "greater", False, None) for k in design.looks]
    for made in range(1, len(looks) + 1):
        verdict = judge([[x] for x in looks[:made]], design)[0]
        if verdict.verdict != "undecided":
            break
    found = stopping(looks[:made], verdict, made == len(looks))
    assert found is not None
    return found.look, found.at_look, found.median_unbiased, found.conditional


def test_the_corrected_estimates_are_median_unbiased_where_the_stopping_look_is_not() -> None:
    """A claim judged at 25, 50, 75 and 100 seeds per arm (O'Brien–Fleming, α = 0.05), true
    Δ = 0.45 sd: Δ̂ at the stopping look overshoots among the experiments that stop at the
    second look; the estimates corrected for stopping do not."""
    design, delta = Design((25, 50, 75, 100)), 0.45
    rng = np.random.default_rng(20261206)
    runs = np.array([_design_run(delta, rng, design) for _ in range(300)])
    look, naive, stagewise, conditional = runs.T
    assert abs(np.median(stagewise) - delta) < 0.04
    assert 0.42 < np.mean(stagewise < delta) < 0.58
    second = look == 1
    assert second.sum() > 50
    assert np.median(naive[second]) - delta > 0.15  # biased away from zero
    assert abs(np.median(conditional[second]) - delta) < 0.09
    assert np.mean(naive) - delta > 0.01  # and on average over all the experiments
