"""What the Experiments tab shows, computed without viser (so it runs off the GUI's threads and
is tested without a server): the experiments with their status per scale, one experiment's
status, curves and verdicts at a scale, and the safe path of one of its runs.

The experiments are the shipped ones, and the other folders `RUNS_DIR/experiments/NAME/`
(experiments run with `gnp-lab experiment run --file`): those are shown from their summary
files and cannot be started here, since the dashboard does not have their file.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from app import store
from app.dashboard.controls import DashboardInputError
from app.dashboard.plots import MAX_POINTS, MeanBand
from app.experiments import harvest, layout, planning
from app.experiments.progress import Counts
from app.experiments.results import ExperimentResults
from app.experiments.spec import SCALES, ExperimentError, ExperimentSpec, Scale
from app.experiments.spec_loading import load_shipped, shipped_names
from app.experiments.spec_tables import check_name
from app.experiments.summary import read_summary
from app.store.catalogue import SUFFIX

NO_EXPERIMENTS = "(none)"
NO_RUNS = "(no runs yet)"
FITNESS = "best_fitness_curve"
REWARD = "reward_per_step"
NO_SUMMARY = "No summary at this scale yet: start the experiment."


@dataclass(frozen=True)
class Entry:
    """An experiment the tab offers: shipped, or saved in the runs dir (with the file it ran
    from when its folder keeps one)."""

    name: str
    spec: ExperimentSpec | None  # None: a folder in the runs dir the dashboard has no file of
    shipped: bool = True
    problem: str = ""  # why a kept file could not be read

    def scales(self, runs_dir: Path) -> tuple[str, ...]:
        """The scales it defines (shipped) or has a summary of (saved)."""
        if self.spec is not None:
            return tuple(self.spec.scales)
        return tuple(s for s in SCALES if layout.summary_path(runs_dir, self.name, s).exists())


def shipped_specs() -> tuple[ExperimentSpec, ...]:
    return tuple(load_shipped(name) for name in shipped_names())


def find_experiments(runs_dir: Path, shipped: Sequence[ExperimentSpec]) -> tuple[Entry, ...]:
    """The shipped experiments, then the runs dir's other experiment folders, by name."""
    entries = [Entry(spec.name, spec) for spec in shipped]
    known = {spec.name for spec in shipped}
    folder = Path(runs_dir) / "experiments"
    if folder.is_dir():
        for path in sorted(folder.iterdir()):
            if path.is_dir() and path.name not in known and _safe_name(path.name):
                try:
                    entries.append(Entry(path.name, layout.saved_spec(runs_dir, path.name), False))
                except ExperimentError as error:
                    entries.append(Entry(path.name, None, False, str(error)))
    return tuple(entries)


def _safe_name(name: str) -> bool:
    try:
        check_name(name)
    except ValueError:
        return False
    return True


@dataclass(frozen=True)
class ScaleCount:
    """Runs done (trained, every condition implemented) out of the runs of one scale."""

    done: int
    total: int
    problems: int = 0  # run files that cannot be used (foreign, unreadable)

    def __str__(self) -> str:
        return f"{self.done}/{self.total}" + (" ⚠" if self.problems else "")


def summary_count(results: ExperimentResults) -> ScaleCount:
    """Runs done according to a summary: a final fitness and every condition's mean reward."""
    done = [results.finished(arm.name) for arm in results.arms]
    return ScaleCount(int(np.sum(done)), len(results.arms) * len(results.seeds))


STATES = planning.StateCache()
"""The run files' states this dashboard has read (a Refresh reads only what changed)."""


def scale_count(entry: Entry, scale: str, runs_dir: Path) -> ScaleCount | None:
    """The entry's runs done at `scale`; None when it has nothing at that scale."""
    if entry.spec is None:
        path = layout.summary_path(runs_dir, entry.name, scale)
        if not path.exists():
            return None
        try:
            return summary_count(read_summary(path))
        except ExperimentError:
            return ScaleCount(0, 0, problems=1)
    if scale not in entry.spec.scales:
        return None
    if not (layout.experiment_dir(runs_dir, entry.name) / scale).is_dir():  # nothing run yet
        runs = len(entry.spec.arms) * len(entry.spec.seed_list(cast(Scale, scale)))
        return ScaleCount(0, runs)
    status = planning.scale_status(entry.spec, scale, runs_dir, read=STATES.inspect)
    return ScaleCount(status.done, len(status.tasks), len(status.problems))


Catalogue = tuple[tuple[Entry, dict[str, ScaleCount | None]], ...]


def catalogue(
    runs_dir: Path,
    shipped: Sequence[ExperimentSpec],
    counted: Callable[[int, int], None] | None = None,
) -> Catalogue:
    """Every experiment with its runs done per scale (reads run files: not for a callback);
    `counted(done, experiments)` is told after each experiment."""
    entries = find_experiments(runs_dir, shipped)
    rows: list[tuple[Entry, dict[str, ScaleCount | None]]] = []
    for done, entry in enumerate(entries, 1):
        counts: dict[str, ScaleCount | None] = {s: scale_count(entry, s, runs_dir) for s in SCALES}
        rows.append((entry, counts))
        if counted is not None:
            counted(done, len(entries))
    return tuple(rows)


def catalogue_table(rows: Catalogue) -> str:
    """A markdown table: each experiment's runs done / total per scale."""
    lines = ["| experiment | " + " | ".join(SCALES) + " |", "|---" * (len(SCALES) + 1) + "|"]
    for entry, counts in rows:
        name = entry.name if entry.shipped else f"{entry.name} (saved)"
        cells = [str(counts[scale]) if counts[scale] is not None else "–" for scale in SCALES]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def progress_line(name: str, scale: str, phase: str, counts: Counts | None) -> str:
    """The tab's line about a started experiment (also what the browser test reads)."""
    line = f"experiment: {name} at {scale} · {phase}"
    if counts is not None:
        line += (
            f" · {counts.runs_done}/{counts.runs} runs done · generations "
            f"{counts.generations_done}/{counts.generations} · conditions "
            f"{counts.conditions_done}/{counts.conditions}"
        )
        under_way = ", ".join(f"{n} {g}/{total}" for n, g, total in counts.under_way[:4])
        if under_way:
            line += f"  \nunder way: {under_way}" + (" …" if len(counts.under_way) > 4 else "")
    return line


def elsewhere(entry: Entry, scale: str, runs_dir: Path) -> tuple[int, Counts] | None:
    """(pid, how far it is) of the entry running in another process at `scale` (an `experiment
    run` in another terminal holds its folder's lock, and wrote the scale it runs there), from
    its run files; None when none is.

    A started scale's runs that changed are read (`STATES`), so a look costs what the
    runs under way wrote, not every file."""
    from app.experiments.lock import holder_elsewhere
    from app.experiments.progress import Progress

    holder = holder_elsewhere(layout.experiment_dir(runs_dir, entry.name))
    if holder is None or holder[1] != scale or entry.spec is None:
        return None  # none, or at another scale
    pid = holder[0]
    status = planning.scale_status(entry.spec, scale, runs_dir, read=STATES.inspect)
    states = {t.key: s for t, s in zip(status.tasks, status.states, strict=True)}
    return pid, Progress(list(status.tasks), states, quiet=True).counts()


# --- one experiment at one scale ----------------------------------------------------------


@dataclass(frozen=True)
class Chart:
    """A chart's points: x, and per arm its mean over runs with its 95% band."""

    x: np.ndarray
    lines: tuple[MeanBand, ...]
    caption: str = ""


NO_CHART = Chart(np.zeros(0), ())


@dataclass(frozen=True)
class ExperimentView:
    """One experiment at one scale, as the tab shows it (every chart computed already)."""

    name: str
    scale: str
    about: str  # markdown: what it compares
    count: ScaleCount | None
    problems: tuple[str, ...]  # why some run files cannot be used
    fitness: Chart
    rewards: dict[str, Chart]  # by condition name, in the experiment's order
    verdicts: str  # markdown
    runs: tuple[str, ...]  # run files of this scale, e.g. "BS-seed0"
    stages: str = ""  # markdown: the looks of the run (an adaptive run's stages)


def build_view(
    entry: Entry,
    scale: str,
    runs_dir: Path,
    live: bool = False,
    seeds: int | None = None,
    since: float | None = None,
) -> ExperimentView:
    """Read what the folder holds: the summary if written, else the run files.

    Args:
        live: the experiment is running: its curves come from the run files (the first
            `seeds` per arm when given, else the scale's), its verdicts and stages from the
            summary only when it was written after `since` (a time.time(): an adaptive run
            writes it after every look).
    """
    spec, name = entry.spec, entry.name
    folder = layout.experiment_dir(runs_dir, name) / scale
    summary = layout.summary_path(runs_dir, name, scale)
    problems: tuple[str, ...] = ()
    results: ExperimentResults | None = None
    count: ScaleCount | None
    verdicts = NO_SUMMARY
    stages = ""
    if live:  # the job's progress counts the runs; reading every file twice is too slow
        count = None
    elif spec is not None and scale in spec.scales and folder.is_dir():
        status = planning.scale_status(spec, scale, runs_dir, read=STATES.inspect)
        count = ScaleCount(status.done, len(status.tasks), len(status.problems))
        problems = tuple(status.problems.values())
    else:
        count = scale_count(entry, scale, runs_dir)
    so_far = live and since is not None and summary.exists() and summary.stat().st_mtime >= since
    try:
        if summary.exists() and (so_far or not live):
            results = read_summary(summary)
            verdicts, stages = verdicts_and_stages(results)
            if so_far:
                verdicts = "Verdicts so far (the last look made):\n\n" + verdicts
        if (live or results is None) and spec is not None and folder.is_dir() and not problems:
            results = harvest.collect(spec, scale, runs_dir, seeds)  # the run files so far
            if not so_far:
                verdicts = "Verdicts: when the experiment finishes (its summary is written)."
    except ExperimentError as error:
        problems += (str(error),)
    runs = tuple(sorted(p.stem for p in folder.glob("*" + SUFFIX))) if folder.is_dir() else ()
    fitness, rewards = NO_CHART, {}
    if results is not None:
        fitness = fitness_chart(results)
        rewards = {c.name: reward_chart(results, c.name) for c in results.conditions}
    return ExperimentView(
        name, scale, about(entry, results), count, problems, fitness, rewards, verdicts, runs,
        stages,
    )  # fmt: skip


def verdicts_and_stages(results: ExperimentResults) -> tuple[str, str]:
    """The verdict tables and the stages table of a summary (markdown), the report's numbers."""
    from app.dashboard.experiment_verdicts import stages_table, verdict_tables
    from app.experiments.report import analyse

    if not results.comparisons:
        return "This experiment makes no comparisons.", ""
    report = analyse(results)
    return verdict_tables(report), stages_table(report)


def about(entry: Entry, results: ExperimentResults | None) -> str:
    """What the experiment compares, in a line or two of markdown."""
    if entry.spec is not None:
        spec = entry.spec
        arms = ", ".join(f"{a.name} ({a.label})" for a in spec.arms)
        conditions = len(spec.conditions)
        saved = "" if entry.shipped else "; saved"
        return (
            f"**{spec.name}** ({spec.source}{saved}): {spec.description}  \narms: {arms}; "
            f"{conditions} implementation conditions"
        )
    if results is None:
        return f"**{entry.name}**: saved experiment with no summary at this scale."
    arms = ", ".join(f"{a.name} ({a.label})" for a in results.arms)
    return f"**{results.name}** ({results.source}; saved): {results.description}  \narms: {arms}"


# --- curves ---------------------------------------------------------------------------------


def _rgb(colour: str) -> tuple[int, int, int]:
    from matplotlib.colors import to_rgb

    red, green, blue = to_rgb(colour)
    return round(255 * red), round(255 * green), round(255 * blue)


def _lines(
    results: ExperimentResults, metric: str, condition: str, window: int = 1
) -> tuple[int, list[MeanBand]]:
    from app.experiments.figures import arm_colours, mean_and_ci, moving_average

    colours = arm_colours(results)  # the report's colours
    lines, length = [], 0
    for arm in results.arms:
        curves = results.curves.get((metric, arm.name, condition))
        if curves is None or curves.size == 0:
            continue
        curves = np.atleast_2d(curves)
        if window > 1:
            curves = moving_average(curves, min(window, curves.shape[1]))
        mean, half_width, n = mean_and_ci(curves)
        label = f"{arm.name} (n = {int(n.max())})"
        lines.append(MeanBand(label, _rgb(colours[arm.name]), mean, half_width))
        length = max(length, len(mean))
    return length, lines


def _trimmed(x: np.ndarray, lines: list[MeanBand]) -> tuple[np.ndarray, list[MeanBand]]:
    """Up to the last point any line has, thinned to at most MAX_POINTS points."""
    if not lines:
        return x[:0], lines
    padded = [
        np.pad(line.mean, (0, len(x) - len(line.mean)), constant_values=np.nan) for line in lines
    ]
    finite = np.flatnonzero(np.isfinite(np.vstack(padded)).any(axis=0))
    end = int(finite[-1]) + 1 if finite.size else 0
    keep = np.unique(np.linspace(0, max(end - 1, 0), min(end, MAX_POINTS)).round().astype(int))

    def cut(values: np.ndarray) -> np.ndarray:
        full = np.pad(values, (0, len(x) - len(values)), constant_values=np.nan)
        return full[keep]

    return x[keep], [MeanBand(ln.label, ln.color, cut(ln.mean), cut(ln.half_width)) for ln in lines]


def fitness_chart(results: ExperimentResults) -> Chart:
    """Best fitness per generation: per arm the mean over seeds and its 95% t-band."""
    length, lines = _lines(results, FITNESS, "")
    x, kept = _trimmed(np.arange(1, length + 1, dtype=np.float64), lines)
    return Chart(x, tuple(kept))


def reward_chart(results: ExperimentResults, condition: str) -> Chart:
    """A condition's reward per step (moving average, as in the report) per arm, captioned."""
    from app.experiments.figures import smoothing_window

    chosen = next(c for c in results.conditions if c.name == condition)
    window = smoothing_window(chosen.steps)
    length, lines = _lines(results, REWARD, condition, window)
    x = np.arange(length, dtype=np.float64) + (window - 1) / 2  # centre of each window
    fault = f" · sensors break at t' = {chosen.fault_step}" if chosen.fault_step is not None else ""
    caption = f"{chosen.label}: reward per step, moving average over {window} steps{fault}"
    x, kept = _trimmed(x, lines)
    return Chart(x, tuple(kept), caption)


# --- runs -----------------------------------------------------------------------------------


def run_file(runs_dir: Path, name: str, scale: str, run: str) -> Path:
    """The file of one of an experiment's runs, only ever inside the runs dir.

    Raises:
        DashboardInputError: no experiment, scale or run is chosen, or the name holds a path.
        RunFileError: the run file does not exist.
    """
    if name == NO_EXPERIMENTS or run == NO_RUNS:
        raise DashboardInputError("choose an experiment and one of its runs first")
    if scale not in SCALES:
        raise DashboardInputError(f"scale must be one of {', '.join(SCALES)}, got {scale!r}")
    try:
        folder = layout.experiment_dir(runs_dir, name) / scale  # refuses a name with a path
    except ExperimentError as error:
        raise DashboardInputError(str(error)) from None
    return store.resolve_run(folder, run)  # refuses a run name with a path
