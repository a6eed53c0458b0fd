"""The dashboard's uPlot charts: reward per step (live), fitness per generation, implementation.

Series data are bounded (the live history holds the last 1000 steps; the implementation curve
is block-averaged to at most `MAX_POINTS`), so a long session never grows a chart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import viser
from viser.uplot import Axis, Legend

import sim
from app.phases.live import RobotSnapshot
from app.views.arena_view import ROBOT_COLORS

MAX_POINTS = 600
SMOOTH = 50
BIN = 10
"""Steps per point of the reward chart."""
REWARD_RANGE = (0.0, 1.08)
"""A reward per step (and so a fitness, Eq. 2.8) lies in 0..1: headroom keeps the 1.0 tick."""
REWARD_TICKS = (0.25, 0.5)
REWARD_AXIS: Axis = {"scale": "y", "incrs": REWARD_TICKS, "space": 16}
"""The reward (and fitness) axis: ticks 16 pixels apart still get their values (short charts)."""
BROKEN_AXIS: Axis = {
    "scale": "n",
    "side": 1,
    "label": "sensors broken",
    "splits": tuple(float(n) for n in range(0, sim.N_SENSORS + 1, 2)),
    "stroke": "#e61414",
    "grid": {"show": False},
    "size": 26,
    "labelSize": 14,
    "labelFont": "11px system-ui, sans-serif",
}
"""The broken-sensor count's own axis, on the right: its dashed line is read there, never
against the reward's scale on the left."""
BROKEN_SCALE = {"n": {"range": (0.0, REWARD_RANGE[1] * sim.N_SENSORS)}}
"""All sensors broken level with a reward of 1, with the reward's headroom (the top tick shows)."""
X_NOT_TIME: dict[str, Any] = {"x": {"time": False}}
LABELS_ONLY: Legend = {"live": False}
"""A legend of the series' names only (no values under the cursor): one line, not two."""
WHOLE_STEPS = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0, 5000.0)
"""Tick spacings for a generation or step axis (no 2.5th generation)."""
FAULT_STYLE: dict[str, Any] = {"stroke": "#e61414", "dash": (6.0, 4.0), "width": 1.5}


def _rgb(color: tuple[int, int, int], alpha: float = 1.0) -> str:
    return f"rgba({color[0]}, {color[1]}, {color[2]}, {alpha})"


def _empty(n_series: int) -> tuple[np.ndarray, ...]:
    return tuple(np.zeros(1) for _ in range(n_series))


def _reward_series(labels: Sequence[str]) -> tuple[dict[str, Any], ...]:
    series: list[dict[str, Any]] = [{"label": "step"}]
    for i, label in enumerate(labels):
        color = ROBOT_COLORS[i]
        short = label if len(label) <= 14 else label[:13] + "…"
        # The raw reward is mostly 0 or 1 step by step: drawn as is it is a wall of vertical
        # lines. Its BIN-step means, a light area, say as much and read at a glance.
        series.append(
            {
                "label": f"{short} ({BIN}-step)",
                "stroke": _rgb(color, 0.35),
                "fill": _rgb(color, 0.12),
                "width": 1.0,
            }
        )
        series.append({"label": f"{SMOOTH}-step mean", "stroke": _rgb(color), "width": 2.5})
    series.append({"label": "broken sensors", "scale": "n", **FAULT_STYLE})
    return tuple(series)


REWARD_TITLE = "Reward per step (robots on show)"
"""The reward chart's title when it names no run (a task run on show)."""


def reward_plot(gui: viser.GuiApi) -> viser.GuiUplotHandle:
    """Reward per step of the robots on show; the broken-sensor count as a dashed line.

    The reward axis runs a little past 1 so its top tick is not cut off; the broken-sensor count
    has its own scale and axis on the right (0 to all sensors).
    """
    series = _reward_series(["robot"])
    return gui.add_uplot(
        data=_empty(len(series)),
        series=series,  # type: ignore[arg-type]
        title=REWARD_TITLE,
        scales={**X_NOT_TIME, "y": {"range": REWARD_RANGE}, **BROKEN_SCALE},
        axes=({"incrs": WHOLE_STEPS}, REWARD_AXIS, BROKEN_AXIS),
        legend=LABELS_ONLY,
        aspect=2.2,
    )


def set_reward_series(plot: viser.GuiUplotHandle, labels: Sequence[str]) -> None:
    """Re-label the reward chart for the robots now on show (one or two)."""
    series = _reward_series(labels)
    if tuple(series) == tuple(plot.series):
        return  # the same robots (e.g. the next generation's best of one run): keep the chart
    plot.data = _empty(len(series))
    plot.series = series  # type: ignore[assignment]


def moving_mean(values: np.ndarray, window: int) -> np.ndarray:
    """Trailing mean over up to `window` values (shorter at the start), same length."""
    values = np.asarray(values, np.float64)
    if len(values) == 0:
        return values
    cumulative = np.concatenate([[0.0], np.cumsum(values)])
    index = np.arange(1, len(values) + 1)
    lower = np.maximum(0, index - window)
    return (cumulative[index] - cumulative[lower]) / (index - lower)


def step_bins(steps: np.ndarray, width: int) -> np.ndarray:
    """Start index of each run of consecutive `steps` in the same block of `width` steps
    (blocks are aligned on whole multiples of `width`, so they stay put as the history slides)."""
    block = np.asarray(steps, np.int64) // width
    return np.flatnonzero(np.diff(block, prepend=block[:1] - 1))


def set_rewards(plot: viser.GuiUplotHandle, robots: Sequence[RobotSnapshot]) -> None:
    """Feed the chart the robots' reward histories (they step together: shared x), one point per
    BIN-step block at its last step: the block's mean reward, the trailing SMOOTH-step mean and
    the most sensors broken in the block."""
    n = min(len(r.rewards) for r in robots)
    if n == 0:
        return
    steps = robots[0].reward_steps[-n:]
    starts = step_bins(steps, BIN)
    ends = np.append(starts[1:], n) - 1
    data: list[np.ndarray] = [steps[ends].astype(np.float64)]
    for robot in robots:
        rewards = np.asarray(robot.rewards[-n:], np.float64)
        block_mean = np.add.reduceat(rewards, starts) / np.diff(np.append(starts, n))
        data += [block_mean, moving_mean(rewards, SMOOTH)[ends]]
    broken = robots[0].broken_counts[-n:]
    data.append(np.maximum.reduceat(broken, starts).astype(np.float64))
    if len(data) == len(plot.series):
        plot.data = tuple(data)


def fitness_plot(gui: viser.GuiApi) -> viser.GuiUplotHandle:
    """Best and mean fitness (Eq. 2.8) per generation."""
    return gui.add_uplot(
        data=_empty(3),
        series=(
            {"label": "generation"},
            {"label": "best", "stroke": "#1f6fd0", "width": 2.0},
            {"label": "mean", "stroke": "#5aa05a", "width": 2.0},
        ),
        title=FITNESS_TITLE,
        scales={**X_NOT_TIME, "y": {"range": REWARD_RANGE}},
        axes=({"incrs": WHOLE_STEPS}, REWARD_AXIS),
        legend=LABELS_ONLY,
        aspect=3.2,
    )


FITNESS_TITLE = "Fitness per generation"
IMPLEMENTATION_TITLE = "Implementation phase"
RETURN_TITLE = "Episode return per generation (task)"


def set_fitness(
    plot: viser.GuiUplotHandle,
    best: np.ndarray,
    mean: np.ndarray,
    returns: bool = False,
    run: str = "",
) -> None:
    """Best and mean per generation of `run` (named in the title): a robot run's fitness on
    0..1, or (`returns`) a task run's episode returns on a scale of their own."""
    kind = RETURN_TITLE if returns else FITNESS_TITLE
    title = f"{kind} · {run}" if run else kind
    if returns and len(best):
        low = min(0.0, float(np.min(mean)))
        high = max(1.0, float(np.max(best))) * 1.08
        # The x range too: a chart re-made for new scales may keep the last run's otherwise.
        x: dict[str, Any] = {"time": False, "range": (0.0, float(max(1, len(best) - 1)))}
        plot.scales = {"x": x, "y": {"range": (low, high)}}  # type: ignore[assignment]
        plot.axes = ({"incrs": WHOLE_STEPS}, {"scale": "y", "space": 16})
    elif not (plot.title or "").startswith(FITNESS_TITLE):  # back from a task run: robot scale
        plot.scales = {**X_NOT_TIME, "y": {"range": REWARD_RANGE}}
        plot.axes = ({"incrs": WHOLE_STEPS}, REWARD_AXIS)
    if plot.title != title:
        plot.title = title
    generations = np.arange(len(best), dtype=np.float64)
    if len(best) == 0:
        plot.data = _empty(3)
        return
    plot.data = (generations, np.asarray(best, np.float64), np.asarray(mean, np.float64))


def block_mean(values: np.ndarray, max_points: int) -> tuple[np.ndarray, np.ndarray]:
    """(x, y): `values` averaged over equal blocks so that at most `max_points` remain; x is
    the first step of each block."""
    values = np.asarray(values, np.float64)
    block = max(1, int(np.ceil(len(values) / max_points)))
    n_blocks = int(np.ceil(len(values) / block))
    padded = np.full(n_blocks * block, np.nan)
    padded[: len(values)] = values
    y = np.nanmean(padded.reshape(n_blocks, block), axis=1)
    return np.arange(n_blocks, dtype=np.float64) * block, y


def implementation_plot(gui: viser.GuiApi) -> viser.GuiUplotHandle:
    """Mean reward per step over the trials of an implementation phase; the fault step."""
    series: tuple[Any, ...] = (
        {"label": "step"},
        {"label": "mean reward/step over trials", "stroke": "#8a3ab9", "width": 2.0},
        {"label": "sensors broken", "scale": "n", **FAULT_STYLE},
    )
    return gui.add_uplot(
        data=_empty(3),
        series=series,
        title=IMPLEMENTATION_TITLE,
        scales={**X_NOT_TIME, **BROKEN_SCALE},
        axes=({}, REWARD_AXIS, {**BROKEN_AXIS, "space": 16, "label": "broken"}),
        legend=LABELS_ONLY,
        aspect=3.2,
    )


def set_implementation(
    plot: viser.GuiUplotHandle, reward: np.ndarray, fault_step: int, broken: int = 0
) -> None:
    """The trials' mean reward per step, and the `broken` sensors from the fault step on."""
    x, y = block_mean(reward, MAX_POINTS)
    plot.data = (x, y, np.where(x >= fault_step, float(broken), 0.0))


@dataclass(frozen=True)
class MeanBand:
    """One line of a mean-and-band chart: a mean over runs and its 95% half-width."""

    label: str
    color: tuple[int, int, int]
    mean: np.ndarray
    half_width: np.ndarray  # NaN where undefined (fewer than 2 runs): no band there


def band_plot(gui: viser.GuiApi, title: str, x_label: str) -> viser.GuiUplotHandle:
    """An empty chart for `set_mean_bands`."""
    return gui.add_uplot(
        data=_empty(2),
        series=({"label": x_label}, {"label": "(nothing yet)"}),
        title=title,
        scales=X_NOT_TIME,
        axes=({"incrs": WHOLE_STEPS}, {}),  # generations and steps: no 2.5th
        aspect=1.6,
    )


def set_mean_bands(plot: viser.GuiUplotHandle, x: np.ndarray, lines: Sequence[MeanBand]) -> None:
    """One bold mean per line with its band filled between faint upper and lower bounds."""
    x_label = plot.series[0].get("label", "x")
    series: list[dict[str, Any]] = [{"label": x_label}]
    data: list[np.ndarray] = [np.asarray(x, np.float64)]
    bands: list[dict[str, Any]] = []
    for line in lines:
        mean = np.asarray(line.mean, np.float64)
        half = np.nan_to_num(np.asarray(line.half_width, np.float64))  # no band: zero width
        faint = {"stroke": _rgb(line.color, 0.35), "width": 1.0}
        series += [
            {"label": line.label, "stroke": _rgb(line.color), "width": 2.0},
            {"label": "+95%", **faint},
            {"label": "−95%", **faint},
        ]
        data += [mean, mean + half, mean - half]
        bands.append({"series": (len(series) - 2, len(series) - 1), "fill": _rgb(line.color, 0.15)})
    if not lines:
        series.append({"label": "(nothing yet)"})
        data = [np.zeros(1), np.zeros(1)]
    plot.data = tuple(data)
    plot.series = tuple(series)  # type: ignore[assignment]
    plot.bands = tuple(bands)  # type: ignore[arg-type]
