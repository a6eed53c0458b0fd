"""The report's figures, drawn on matplotlib `Figure` objects with the Agg canvas.

No pyplot and no `matplotlib.use`: each figure gets its own `FigureCanvasAgg`, so drawing a
report changes no process-wide matplotlib state. Every band and error bar is a 95% Student-t
interval of the mean over runs (seeds): mean ± t(0.975, n − 1)·sd/√n with the n runs that have
a finite value there; with one run there is no interval. Missing curves are skipped.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy import stats as scipy_stats

from app.experiments.results import METRICS, Comparison, Condition, ExperimentResults

REWARD_SMOOTHING_STEPS = 50  # centred moving average of the per-step reward (at most T / 10)
DPI = 110
_NO_VALUE = np.array([np.nan])  # a metric not recorded


@dataclass(frozen=True)
class FigureFile:
    """A figure saved next to the report, with what the report says about it."""

    file: str  # name relative to the report
    title: str
    caption: str


def mean_and_ci(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column-wise mean over runs and the half-width of its 95% t-interval.

    Args:
        samples: (n_runs, L) values; NaN (unfinished runs) are left out column by column.

    Returns:
        (mean, half_width, n) of shape (L,); mean is NaN where no run is finite and half_width
        is NaN where fewer than 2 are.
    """
    samples = np.asarray(samples, dtype=float)
    finite = np.isfinite(samples)
    n = finite.sum(axis=0)
    filled = np.where(finite, samples, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = filled.sum(axis=0) / n
        squares = np.where(finite, (samples - mean) ** 2, 0.0).sum(axis=0)
        sd = np.sqrt(squares / (n - 1))
        half_width = scipy_stats.t.ppf(0.975, n - 1) * sd / np.sqrt(n)
    mean = np.where(n > 0, mean, np.nan)
    half_width = np.where(n > 1, half_width, np.nan)
    return mean, half_width, n


def moving_average(curves: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average of each row over `window` points, valid part only."""
    kernel = np.ones(window) / window
    return np.stack([np.convolve(row, kernel, mode="valid") for row in np.atleast_2d(curves)])


def smoothing_window(steps: int) -> int:
    """The per-step reward's smoothing window for a curve of `steps` points."""
    return max(1, min(REWARD_SMOOTHING_STEPS, steps // 10))


def _new_figure(width: float = 7.0, height: float = 4.0) -> Figure:
    figure = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def arm_colours(results: ExperimentResults) -> dict[str, str]:
    """Each arm's matplotlib colour ("C0", "C1", ...), in the order of the arms."""
    return {arm.name: f"C{i % 10}" for i, arm in enumerate(results.arms)}


def _scalar_mean_ci(values: np.ndarray) -> tuple[float, float, int]:
    """Mean over runs of one value per run, its 95% t half-width (0 when undefined) and n."""
    mean, half_width, n = mean_and_ci(np.asarray(values, dtype=float).reshape(-1, 1))
    return float(mean[0]), float(np.nan_to_num(half_width[0])), int(n[0])


def _plot_mean_band(axes: Axes, x: np.ndarray, curves: np.ndarray, colour: str, label: str) -> None:
    mean, half_width, n = mean_and_ci(curves)
    axes.plot(x, mean, color=colour, lw=1.4, label=f"{label} (n = {int(n.max())})")
    if np.any(np.isfinite(half_width)):
        axes.fill_between(x, mean - half_width, mean + half_width, color=colour, alpha=0.2, lw=0)


def fitness_figure(results: ExperimentResults) -> Figure | None:
    """Best fitness per generation, mean over runs with its 95% band, one line per arm."""
    metric = METRICS["best_fitness_curve"]
    colours = arm_colours(results)
    figure = _new_figure()
    axes = figure.add_subplot()
    drawn = False
    for arm in results.arms:
        curves = results.curves.get((metric.name, arm.name, ""))
        if curves is None or curves.size == 0:
            continue
        curves = np.atleast_2d(curves)
        generations = np.arange(1, curves.shape[1] + 1)
        _plot_mean_band(axes, generations, curves, colours[arm.name], arm.label)
        drawn = True
    if not drawn:
        return None
    axes.set(xlabel="generation", ylabel=metric.label, title="Training: best fitness")
    axes.grid(alpha=0.3)
    axes.legend(loc="lower right", fontsize="small")
    return figure


def reward_figure(results: ExperimentResults, condition: Condition) -> Figure | None:
    """Smoothed reward per step over one condition's implementation, one line per arm."""
    metric = METRICS["reward_per_step"]
    colours = arm_colours(results)
    figure = _new_figure()
    axes = figure.add_subplot()
    window = smoothing_window(condition.steps)
    drawn = False
    for arm in results.arms:
        curves = results.curves.get((metric.name, arm.name, condition.name))
        if curves is None or curves.size == 0:
            continue
        curves = np.atleast_2d(curves)
        window = min(window, curves.shape[1])
        smoothed = moving_average(curves, window)
        steps = np.arange(smoothed.shape[1]) + (window - 1) / 2  # centre of each window
        _plot_mean_band(axes, steps, smoothed, colours[arm.name], arm.label)
        drawn = True
    if not drawn:
        return None
    if condition.fault_step is not None:
        axes.axvline(
            condition.fault_step,
            color="black",
            ls="--",
            lw=1,
            label=f"{condition.broken_count} sensor(s) break (t' = {condition.fault_step})",
        )
    axes.set(
        xlabel="step t of the implementation",
        ylabel=f"{metric.label} (moving average, {window} steps)",
        title=f"Implementation: {condition.label}",
    )
    axes.grid(alpha=0.3)
    axes.legend(loc="best", fontsize="small")
    return figure


def fault_conditions(results: ExperimentResults) -> tuple[Condition, ...]:
    """Conditions with after-fault values, when at least two broken counts differ."""
    metric = "mean_reward_after_fault"
    with_values = tuple(
        c
        for c in results.conditions
        if any(
            np.isfinite(results.scalars.get((metric, arm.name, c.name), _NO_VALUE)).any()
            for arm in results.arms
        )
    )
    return with_values if len({c.broken_count for c in with_values}) >= 2 else ()


def fault_figure(results: ExperimentResults) -> Figure | None:
    """Mean reward after the fault against the number of broken sensors, per arm (95% t-CI)."""
    metric = METRICS["mean_reward_after_fault"]
    conditions = fault_conditions(results)
    if not conditions:
        return None
    colours = arm_colours(results)
    noise_levels = sorted({c.noise_sigma for c in conditions})
    figure = _new_figure()
    axes = figure.add_subplot()
    offsets = np.linspace(-0.08, 0.08, len(results.arms) * len(noise_levels))
    offset = iter(offsets)
    for arm in results.arms:
        for sigma in noise_levels:
            series = sorted(
                (c for c in conditions if c.noise_sigma == sigma), key=lambda c: c.broken_count
            )
            points = [
                _scalar_mean_ci(results.scalars.get((metric.name, arm.name, c.name), _NO_VALUE))
                for c in series
            ]
            runs = max(n for _, _, n in points)
            label = arm.label if len(noise_levels) == 1 else f"{arm.label}, σ = {sigma:g}"
            label += f" (n = {runs})"
            x = np.array([c.broken_count for c in series]) + next(offset)
            axes.errorbar(
                x,
                [mean for mean, _, _ in points],
                yerr=[half_width for _, half_width, _ in points],
                color=colours[arm.name],
                marker="o",
                capsize=3,
                ls="-" if sigma == noise_levels[0] else ":",
                label=label,
            )
    axes.set_xticks(sorted({c.broken_count for c in conditions}))
    axes.set(
        xlabel="number of broken sensors",
        ylabel=metric.label,
        title="Reward after the fault",
    )
    axes.grid(alpha=0.3)
    axes.legend(loc="best", fontsize="small")
    return figure


def runs_figure(
    results: ExperimentResults, comparison: Comparison, delta: DeltaBar | None = None
) -> Figure | None:
    """Each run's value of a comparison's metric for its two arms (or, paired, its one arm in
    two conditions or on two metrics, each run's two values joined) with their means, and
    beside them the difference with the verdict's interval."""
    metric = METRICS[comparison.metric]
    colours = arm_colours(results)
    figure = _new_figure(5.2, 3.2)
    axes, right = figure.subplots(1, 2, width_ratios=[3, 1])
    drawn = False
    keys = comparison.keys()
    found = [results.scalars.get(key) for key in keys]
    if comparison.paired and found[0] is not None and found[1] is not None:
        both = np.isfinite(found[0]) & np.isfinite(found[1])
        for a_value, b_value in zip(found[0][both], found[1][both], strict=True):
            axes.plot([0, 1], [a_value, b_value], color="0.75", linewidth=0.8, zorder=2)
    for position, ((_, name, _), values) in enumerate(zip(keys, found, strict=True)):
        if values is None:
            continue
        finite = values[np.isfinite(values)]
        spread = finite.size > 1 and not comparison.paired  # paired: on the lines joining runs
        jitter = np.linspace(-0.12, 0.12, finite.size) if spread else np.zeros(finite.size)
        axes.scatter(position + jitter, finite, color=colours[name], s=18, zorder=3)
        if finite.size:
            axes.plot(position + 0.3, finite.mean(), color="black", marker="_", markersize=14)
        drawn = drawn or finite.size > 0
    if not drawn:
        return None
    labels = list(comparison.side_names())
    if comparison.within_arm:  # one arm: its name over what tells the sides apart
        labels = [f"{comparison.a}\n{label}" for label in labels]
    axes.set_xticks([0, 1], labels)
    axes.set_xlim(-0.5, 1.6)
    axes.set(ylabel=metric.label, title=comparison.name)
    axes.title.set_fontsize("medium")
    axes.grid(alpha=0.3, axis="y")
    _delta_panel(right, delta)
    return figure


def _delta_panel(axes: Axes, delta: DeltaBar | None) -> None:
    axes.axhline(0.0, color="0.4", linestyle="--", linewidth=0.8)
    axes.set_xticks([0], ["a − b"])
    axes.set_xlim(-0.6, 0.6)
    axes.grid(alpha=0.3, axis="y")
    if delta is None or not np.isfinite(delta.difference):
        return
    if np.isfinite(delta.low):
        axes.errorbar(
            0,
            delta.difference,
            yerr=[[delta.difference - delta.low], [delta.high - delta.difference]],
            color="black",
            marker="o",
            capsize=4,
        )
    else:
        axes.plot(0, delta.difference, "ko")
    if delta.margin is not None:
        signs = {"greater": [1], "less": [-1], "equivalent": [-1, 1]}[delta.direction]
        for sign in signs:
            axes.axhline(sign * delta.margin, color="0.3", linestyle=":", linewidth=1)
    axes.set_title(delta.label, fontsize="small")


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-") or "x"


@dataclass(frozen=True)
class SavedFigures:
    overview: tuple[FigureFile, ...]  # training, each condition's reward, the fault sweep
    runs: tuple[FigureFile | None, ...]  # per comparison, aligned with results.comparisons


FIGURE_FILES = ("fitness.png", "fault.png", "reward-*.png", "runs-*.png")
"""The names `save_figures` gives its PNGs (as glob patterns)."""


@dataclass(frozen=True)
class DeltaBar:
    """A comparison's verdict interval, drawn beside its runs: the same interval as the table."""

    difference: float
    low: float
    high: float
    margin: float | None  # the thesis's effect (equivalence: ±margin), in the metric's units
    direction: str
    label: str  # the interval's coverage, e.g. "99.6%"


def save_figures(
    results: ExperimentResults,
    out_dir: Path,
    deltas: Sequence[DeltaBar | None] = (),
    keep_curves: bool = False,
) -> SavedFigures:
    """Draw every figure the results allow and save each as a PNG in `out_dir`.

    `deltas` (per comparison) adds the verdict's interval of the difference beside its runs.
    With `keep_curves`, a curve figure that the results cannot draw (no curves: results read
    back from values.csv) keeps the folder's earlier file; every other earlier PNG goes.
    """
    kept = {f.name for f in out_dir.glob("*.png")} if keep_curves else set()
    for pattern in FIGURE_FILES:
        for stale in out_dir.glob(pattern):
            if not (pattern in ("fitness.png", "reward-*.png") and stale.name in kept):
                stale.unlink()

    def save(figure: Figure | None, file: str, title: str, caption: str) -> FigureFile | None:
        if figure is None:
            if file in kept and (out_dir / file).exists():
                return FigureFile(file, title, caption)
            return None
        figure.savefig(out_dir / file, dpi=DPI)
        return FigureFile(file, title, caption)

    overview = [
        save(
            fitness_figure(results),
            "fitness.png",
            "Best fitness over generations (cf. Fig. 3.6)",
            "Best fitness of each generation; line: mean over runs, band: 95% t-interval of "
            "the mean over runs (none with a single run).",
        )
    ]
    for index, condition in enumerate(results.conditions):
        fault = (
            f" The dashed line marks the fault step t' = {condition.fault_step}."
            if condition.fault_step is not None
            else ""
        )
        overview.append(
            save(
                reward_figure(results, condition),
                f"reward-{index}-{_slug(condition.name)}.png",
                f"Reward per step: {condition.label} (cf. Fig. 3.7)",
                "Reward per step averaged over the condition's trials, smoothed by a centred "
                f"moving average over {smoothing_window(condition.steps)} steps; line: mean "
                f"over runs, band: 95% t-interval of the mean over runs.{fault}",
            )
        )
    overview.append(
        save(
            fault_figure(results),
            "fault.png",
            "Reward after the fault against broken sensors (cf. Fig. 3.9)",
            "Mean reward per step from the fault step on; points: mean over runs (shifted "
            "slightly per arm for legibility), error bars: 95% t-interval of the mean over runs.",
        )
    )
    bars = list(deltas) or [None] * len(results.comparisons)
    runs = tuple(
        save(
            runs_figure(results, comparison, bar),
            f"runs-{index}-{_slug(comparison.name)}.png",
            f"Runs: {comparison.name}",
            "One point per run (the unit of analysis), black: mean over runs; right: the "
            "difference a − b with the verdict's interval (the table's), dashed at 0, dotted "
            "at the thesis's effect.",
        )
        for index, (comparison, bar) in enumerate(zip(results.comparisons, bars, strict=True))
    )
    return SavedFigures(tuple(f for f in overview if f is not None), runs)
