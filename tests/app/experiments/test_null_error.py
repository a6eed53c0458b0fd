"""The family-wise error of wrong verdicts with every claim's Δ = 0, simulated.

Each simulated experiment has the claim structure of a real one (a pre-registered decisive
spec's primary claims, or a committed report's claims): its arms, the metrics and conditions
each claim compares, paired or not, its direction, its margin and its looks. Every value has
the same mean, so Δ = 0 for every claim, and the experiment is judged as `report.analyse`
judges it: `sequential.judge` over the looks' prefixes a[:n] of every claim's runs. A verdict
is wrong when it says the data rule out Δ = 0: `held` or `reversed` for a directional claim,
`ruled out` for an equivalence claim (Δ = 0 lies inside its ±margin; `held` is right there).
The family-wise error is the share of experiments with any wrong verdict; it must be at most
α, within Monte Carlo error (2.6 binomial standard errors at α).

Speed: `judge` costs milliseconds per experiment (a scalar t quantile per claim and look, 0.1 s
for 39 claims), so the runs are drawn for many experiments at once and `judge` is called only
on the experiments that can hold a wrong verdict (`may_err`, about one in ten or twenty); the
others have none whatever it decides, which `test_the_screen_drops_no_wrong_verdict` checks.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from scipy import stats as scipy_stats

from app.experiments import sequential
from app.experiments.results import Direction
from app.experiments.sequential import ClaimData, Design, judge, nominal_level
from app.experiments.spec_loading import load_shipped

ALPHA = sequential.ALPHA
MC_Z = 2.6  # standard errors of the estimate allowed above α
RHO = 0.5  # correlation of one run's values on different metrics and conditions
SD = 0.1  # sd of a run's value (decisive designs)
BASE = 0.5  # every value's mean: Δ = 0 for every claim
CHUNK = 2000  # experiments drawn at once
DOCS = Path(__file__).resolve().parents[3] / "docs" / "experiments"
DECISIVE = ("ch3-bs-rl-decisive", "ch5-cs-bs-rl-decisive")
REPORTS = tuple(sorted(p.parent.name for p in DOCS.glob("*/report.json")))


@dataclass(frozen=True)
class Claim:
    a: int  # index of side a's values among the structure's keys
    b: int
    direction: Direction
    paired: bool
    margin_for: Callable[[float], float | None]  # the margin in units, given b's mean

    def wrong(self, verdict: str) -> bool:
        """Whether the verdict rules out Δ = 0."""
        if self.direction == "equivalent":
            return verdict == "ruled out"
        return verdict in ("held", "reversed")


@dataclass(frozen=True)
class Structure:
    """The claims of one experiment over the values of its (metric, arm, condition) keys."""

    name: str
    claims: tuple[Claim, ...]
    key_arm: tuple[int, ...]  # per key, the index of its arm
    key_sd: tuple[float, ...]
    design: Design

    @property
    def arms(self) -> int:
        return max(self.key_arm) + 1


def _index(items: list[str], item: str) -> int:
    if item not in items:
        items.append(item)
    return items.index(item)


def decisive_structure(name: str) -> Structure:
    """A decisive spec's primary claims (the family `judge` sees) at its design's looks."""
    spec = load_shipped(name)
    assert spec.design is not None
    keys: list[str] = []
    arms: list[str] = []
    key_arm: dict[int, int] = {}
    claims = []
    for c in spec.comparisons_info():  # the claims as the statistics see them
        if c.family != "primary":
            continue
        both = c.keys()
        sides = [_index(keys, repr(key)) for key in both]
        for side, key in zip(sides, both, strict=True):
            key_arm[side] = _index(arms, key[1])
        claims.append(Claim(sides[0], sides[1], c.direction, c.paired, c.margin_for))
    return Structure(
        name,
        tuple(claims),
        tuple(key_arm[i] for i in range(len(keys))),
        (SD,) * len(keys),
        Design(tuple(spec.design.looks)),
    )


def report_structure(name: str) -> Structure:
    """A committed report's primary claims (the family `judge` sees; a report without
    families judged every claim), each side with the report's sd of its runs (SD when it has
    none), the margin in units the report used and the report's planned looks (one look at
    every seed when not adaptive, as `report.looks_made`). A report that stopped early made
    only the first looks; `judge` decides online (a look's verdicts never depend on later
    looks), so its verdicts are those of the planned looks' prefix and simulating every
    planned look covers it."""
    report = json.loads((DOCS / name / "report.json").read_text(encoding="utf-8"))
    keys: list[str] = []
    arms: list[str] = []
    key_arm: dict[int, int] = {}
    key_sd: dict[int, float] = {}
    claims = []
    for c in report["comparisons"]:
        if c.get("family", "primary") != "primary":
            continue
        condition = c["condition"] or ""
        key_a = (c["metric"], c["a"]["name"], condition)
        key_b = (c["metric_b"] or c["metric"], c["b"]["name"], c["condition_b"] or condition)
        sides = [_index(keys, repr(key)) for key in (key_a, key_b)]
        for side, key, arm in zip(sides, (key_a, key_b), (c["a"], c["b"]), strict=True):
            key_arm[side] = _index(arms, key[1])
            key_sd.setdefault(side, SD if arm["sd"] is None else float(arm["sd"]))
        units = None if c["margin"] is None else c["margin"]["in_units"]

        def margin(_mean_b: float, units: float | None = units) -> float | None:
            return units

        claims.append(Claim(sides[0], sides[1], c["direction"], c["paired"], margin))
    if report["looks_planned"]:
        design = Design(tuple(report["looks_planned"]))
    else:
        design = Design((len(report["seeds"]),))
    return Structure(
        name,
        tuple(claims),
        tuple(key_arm[i] for i in range(len(keys))),
        tuple(key_sd[i] for i in range(len(keys))),
        design,
    )


def draw(structure: Structure, rng: np.random.Generator, experiments: int) -> np.ndarray:
    """Every key's runs, (experiments, keys, seeds), all with mean BASE.

    Claims are not independent, as in the real experiments: claims share arms (one arm
    against two others, or two arms compared on several metrics and conditions), and one
    run's values on different metrics and conditions share a per-run (per arm and seed)
    component, correlation RHO, so a within-arm (paired) claim's two sides are correlated
    pairs and the claims over one arm's runs are correlated. Different arms are independent
    (the decisive specs and the reports declare their between-arm claims unpaired).
    """
    seeds = structure.design.looks[-1]
    run = rng.standard_normal((experiments, structure.arms, seeds))
    own = rng.standard_normal((experiments, len(structure.key_arm), seeds))
    z = math.sqrt(RHO) * run[:, list(structure.key_arm), :] + math.sqrt(1 - RHO) * own
    return BASE + np.asarray(structure.key_sd)[None, :, None] * z


@dataclass(frozen=True)
class _Look:
    """One claim at one look, over a batch of experiments: its interval's pieces."""

    diff: np.ndarray  # Δ's estimate, the claimed side positive ("less" flipped)
    se: np.ndarray
    df: np.ndarray | float  # Welch's, or n − 1 paired
    margin: np.ndarray  # in units, NaN when none


def _looks(structure: Structure, values: np.ndarray) -> list[list[_Look]]:
    """Per look, per claim: the interval's pieces as `sequential.interval` computes them."""
    out = []
    for n in structure.design.looks:
        claims = []
        for c in structure.claims:
            a, b = values[:, c.a, :n], values[:, c.b, :n]
            if c.paired:
                d = a - b
                diff = d.mean(axis=1)
                se = d.std(axis=1, ddof=1) / math.sqrt(n)
                df: np.ndarray | float = n - 1.0
            else:
                wa, wb = a.var(axis=1, ddof=1) / n, b.var(axis=1, ddof=1) / n
                diff = a.mean(axis=1) - b.mean(axis=1)
                se = np.sqrt(wa + wb)
                df = (wa + wb) ** 2 / ((wa**2 + wb**2) / (n - 1))
            margins = [c.margin_for(float(x)) for x in b.mean(axis=1)]
            margin = np.array([math.nan if x is None else x for x in margins])
            sign = -1.0 if c.direction == "less" else 1.0
            claims.append(_Look(sign * diff, se, df, margin))
        out.append(claims)
    return out


def may_err(structure: Structure, values: np.ndarray, alpha: float) -> np.ndarray:
    """Per experiment, whether `judge` (at family-wise `alpha`) can give it a wrong verdict.

    A screen that `judge` is called behind, sound whatever `judge`'s stepping does as long as
    every share is alpha / r with r at least the number of claims it never decides:

    - a wrong verdict needs the claim's interval to exclude 0 at some look (held: low > 0;
      reversed: high < 0; an equivalence claim ruled out: outside ±margin), and a narrower
      interval (a larger level, a larger share) excludes 0 whenever a wider one does;
    - a claim decided (any verdict) at a share of at most alpha / r is decided at that share's
      level `nominal_level(…, alpha / r)`; start from r = 1 (share alpha), count the claims
      that level could decide at some look (every equivalence claim, to be safe: its `held`
      needs no exclusion of 0), and the others hold a share throughout: r ≥ m − decidable.
      Repeat at the smaller share until r stops growing.

    An experiment in which no claim's interval (Welch or paired, as `interval`) excludes 0 at
    that share's level at any look gets no wrong verdict; the screen test below checks this
    against `judge` on experiments judged in full.
    """
    design, m = structure.design, len(structure.claims)
    looks = _looks(structure, values)
    hair = 1 - 1e-9  # intervals a hair narrower than `judge`'s: rounding never hides one

    def half_widths(r: np.ndarray, k: int) -> list[np.ndarray]:
        level = np.ones(r.shape)
        for j in np.unique(r):
            level[r == j] = nominal_level(design.fractions[: k + 1], k, alpha / j)
        return [scipy_stats.t.ppf(1 - level / 2, c.df) * c.se * hair for c in looks[k]]

    r = np.ones(values.shape[0], dtype=int)
    while True:
        decidable = np.zeros((m, values.shape[0]), dtype=bool)
        excludes_0 = np.zeros(values.shape[0], dtype=bool)
        for k in range(len(design.looks)):
            for i, (c, h) in enumerate(zip(looks[k], half_widths(r, k), strict=True)):
                excluded = np.abs(c.diff) > h
                excludes_0 |= excluded
                ruled_out = c.diff + h < c.margin  # False where there is no margin (NaN)
                equivalence = structure.claims[i].direction == "equivalent"
                decidable[i] |= excluded | ruled_out | equivalence
        grown = np.maximum(r, m - decidable.sum(axis=0))
        if np.array_equal(grown, r):
            return excludes_0
        r = grown


def wrong_verdicts(structure: Structure, values: np.ndarray, alpha: float) -> bool:
    """Whether one experiment (keys × seeds) gets a wrong verdict, judged as
    `report.analyse` judges: every claim's runs cut at each look, a[:n] and b[:n]."""
    looks = [
        [
            ClaimData(
                values[c.a, :n],
                values[c.b, :n],
                c.direction,
                c.paired,
                c.margin_for(float(np.nanmean(values[c.b, :n]))),
            )
            for c in structure.claims
        ]
        for n in structure.design.looks
    ]
    verdicts = judge(looks, structure.design, alpha)
    return any(c.wrong(v.verdict) for c, v in zip(structure.claims, verdicts, strict=True))


@dataclass(frozen=True)
class Estimate:
    experiments: int
    wrong: int
    judged: int  # experiments passed to `judge` (the others cannot err)

    @property
    def fwer(self) -> float:
        return self.wrong / self.experiments

    @property
    def bound(self) -> float:
        """α plus MC_Z binomial standard errors of an estimate at α."""
        return ALPHA + MC_Z * math.sqrt(ALPHA * (1 - ALPHA) / self.experiments)

    def __str__(self) -> str:
        return (
            f"FWER {self.fwer:.4f} ({self.wrong}/{self.experiments}; bound {self.bound:.4f}; "
            f"{self.judged} judged)"
        )


def family_wise_error(
    structure: Structure, experiments: int, seed: int, alpha: float = ALPHA
) -> Estimate:
    """The share of `experiments` null experiments with a wrong verdict, `judge` at `alpha`."""
    rng = np.random.default_rng(seed)
    wrong = judged = 0
    for start in range(0, experiments, CHUNK):
        values = draw(structure, rng, min(CHUNK, experiments - start))
        for i in np.flatnonzero(may_err(structure, values, alpha)):
            judged += 1
            wrong += wrong_verdicts(structure, values[i], alpha)
    return Estimate(experiments, wrong, judged)


def check(structure: Structure, estimate: Estimate) -> None:
    print(f"\n{structure.name}: {len(structure.claims)} claims, looks {structure.design.looks}: "
          f"{estimate}")  # fmt: skip
    assert estimate.fwer <= estimate.bound, (
        f"{structure.name}: the family-wise error of wrong verdicts under Δ = 0 exceeds α: "
        f"{estimate}"
    )


# --- the decisive designs (issue: at least 20,000 simulated experiments) ---------------------


@pytest.mark.slow
@pytest.mark.parametrize("name", DECISIVE)
def test_decisive_design_keeps_the_family_wise_error(name: str) -> None:
    structure = decisive_structure(name)
    assert structure.design.looks == (25, 50, 75, 100)
    assert len(structure.claims) == {"ch3-bs-rl-decisive": 3, "ch5-cs-bs-rl-decisive": 4}[name]
    check(structure, family_wise_error(structure, 20_000, seed=20261203 + DECISIVE.index(name)))


@pytest.mark.slow
@pytest.mark.parametrize(
    "name",
    [*DECISIVE, "ch2-reward-source-small", "physics-equivalence-small", "ch4-exponent-small"],
)
def test_the_screen_drops_no_wrong_verdict(name: str) -> None:
    # Every experiment judged, the screened-out ones included: none of those errs. At a
    # family-wise 0.2 wrong verdicts are common, so the screen's edge is exercised. The
    # structures: unpaired claims sharing arms, paired claims, equivalence claims, relative
    # margins.
    structure = decisive_structure(name) if name in DECISIVE else report_structure(name)
    rng = np.random.default_rng(5)
    wrong_at_02 = 0
    for alpha in (ALPHA, 0.2):
        values = draw(structure, rng, 200)
        screened = may_err(structure, values, alpha)
        wrong = np.array([wrong_verdicts(structure, v, alpha) for v in values])
        assert not np.any(wrong & ~screened), f"the screen dropped a wrong verdict at {alpha}"
        assert (~screened).sum() > (50 if alpha == ALPHA else 0)
        wrong_at_02 += int(wrong.sum()) if alpha > ALPHA else 0
    assert wrong_at_02 > 5


# --- the committed reports' claim structures ---------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("name", REPORTS)
def test_committed_report_structure_keeps_the_family_wise_error(name: str) -> None:
    structure = report_structure(name)
    check(structure, family_wise_error(structure, 2000, seed=7 + REPORTS.index(name)))


# --- the simulation has teeth -------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("name", DECISIVE)
def test_without_holm_the_simulation_finds_the_excess(name: str) -> None:
    # Every claim at the full α over the looks (α × claims shared among the claims): no
    # multiplicity adjustment, so the family-wise error of the same null experiments must
    # exceed α beyond Monte Carlo error, or the simulation could not see a broken judge.
    structure = decisive_structure(name)
    estimate = family_wise_error(
        structure, 2000, seed=99 + DECISIVE.index(name), alpha=ALPHA * len(structure.claims)
    )
    print(f"\n{name}, unadjusted over claims: {estimate}")
    assert estimate.fwer > estimate.bound, f"{name}: no excess without Holm: {estimate}"
