"""Take a run's results out of GNP Lab: a controller file, a GraphViz graph, CSV tables, and a
replay folder any static web server shows (docs/export.md).

Every export is written into a fresh folder next to `out` and renamed to `out` at the end, so an
existing non-empty folder is never touched and a failed export leaves nothing half-written.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
from collections.abc import Callable
from pathlib import Path

from app.brains.registry import family_of
from app.export.controller import write_controller
from app.export.graph import graph_dot, transition_counts
from app.export.tables import write_fitness, write_implementations
from app.store import RunFileError, RunReader


class ExportError(ValueError):
    """An export that cannot be made as asked (the message says why)."""


def check_run(reader: RunReader, generation: int | None) -> int:
    """The generation to export (default: the final elite's) of a finished run.

    Raises:
        ExportError: the run has not finished, or the generation is not in it.
    """
    done = reader.generations_done
    if not reader.finished:
        total = reader.config.training.generations
        raise ExportError(
            f"{reader.path.name} has not finished training ({done} of {total} generations); "
            "export a finished run"
        )
    if generation is None:
        return done - 1
    if not -done <= generation < done:
        raise ExportError(
            f"{reader.path.name} has no generation {generation} (generations 0..{done - 1})"
        )
    return generation % done


def check_out(out: Path) -> None:
    """Refuse an `out` that exists and is not an empty folder (nothing is overwritten)."""
    if out.is_dir():
        if any(out.iterdir()):
            raise ExportError(f"{out} exists and is not empty; nothing was written")
    elif out.exists():
        raise ExportError(f"{out} exists and is not a folder; nothing was written")


def _publish(out: Path, fill: Callable[[Path], object]) -> Path:
    """Fill a fresh folder next to `out`, then move it to `out` (which must be absent or empty)."""
    check_out(out)
    # The folders made for it, innermost first: a failed export takes them away again.
    made = [folder for folder in (out.parent, *out.parent.parents) if not folder.exists()]
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = out.parent / f".{out.name}.export-{os.getpid()}-{secrets.token_hex(4)}"
    try:
        staging.mkdir()  # with the umask's permissions, as `out` would have
        fill(staging)
        check_out(out)  # still absent or empty
        if out.is_dir():
            out.rmdir()
        staging.rename(out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        for folder in made:
            with contextlib.suppress(OSError):  # not empty: something else wrote there meanwhile
                folder.rmdir()
        raise
    return out


def write_exports(reader: RunReader, generation: int, folder: Path) -> list[Path]:
    """Write controller.json, graph.dot, fitness.csv and the implementation tables into `folder`."""
    paths = [write_controller(reader, generation, folder / "controller.json")]
    family = family_of(reader.config)
    cfg = family.graph_config
    if cfg is None:  # no node graph to draw
        paths.append(write_fitness(reader, folder / "fitness.csv"))
        return paths + write_implementations(reader, folder)
    individual = family.best(reader, generation)
    final = generation == reader.generations_done - 1
    elite = reader.elite() if final else None
    transitions = (
        transition_counts(elite.trace["node"][0], elite.trace["count"][0])
        if elite is not None
        else None
    )
    title = (
        f"best of generation {generation} of run {reader.path.stem} ({cfg.method}, {cfg.judgment})"
    )
    graph = folder / "graph.dot"
    graph.write_text(graph_dot(cfg, individual, transitions, title), encoding="utf-8")
    paths.append(graph)
    paths.append(write_fitness(reader, folder / "fitness.csv"))
    paths += write_implementations(reader, folder)
    return paths


def export_run(run_path: Path, out: Path, generation: int | None = None) -> Path:
    """Export a finished run's best of `generation` (default: the final elite) into `out`.

    Raises:
        RunFileError: the run file is missing or unreadable.
        ExportError: unfinished run, unknown generation, or `out` exists and is not empty.
    """
    with RunReader(run_path) as reader:
        chosen = check_run(reader, generation)
        return _publish(Path(out), lambda folder: write_exports(reader, chosen, folder))


def export_replay(run_path: Path, out: Path, generation: int | None = None) -> Path:
    """Write a static replay folder of a finished run's final elite into `out`.

    Raises:
        RunFileError: the run file is missing or unreadable.
        ExportError: unfinished run, a generation other than the final one (only the final
            elite's life is recorded), or `out` exists and is not empty.
    """
    from app.export.replay import write_replay

    with RunReader(run_path) as reader:
        final = check_run(reader, None)
        family = family_of(reader.config)
        if family.graph_config is None:
            raise ExportError(
                f"{reader.path.name} is a {family.name} run; replays show runs with a node "
                "graph (GNP) only"
            )
        if generation is not None and check_run(reader, generation) != final:
            raise ExportError(
                f"only the final elite's life (generation {final}) is recorded in "
                f"{reader.path.name}; a replay of generation {generation} cannot be made"
            )
        return _publish(Path(out), lambda folder: write_replay(reader, folder))


__all__ = ["ExportError", "RunFileError", "check_out", "check_run", "export_replay", "export_run"]
