"""`gnp-lab export`: the subcommand's arguments and handler (registered in app/cli.py)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from app.settings.cli_options import add_run_name, add_runs_dir
from app.store import resolve_run
from app.system.exit_codes import EXIT_ERROR
from app.tasks.common import is_task_run


def add_export_parser(commands: Any) -> argparse.ArgumentParser:
    """Add `export` to the subcommands of `gnp-lab`."""
    export = commands.add_parser(
        "export",
        help="export a run's controller, graph and tables, or a replay folder",
        description="Write the best individual of a generation (default: the final elite) of a "
        "finished run into a new folder: controller.json, graph.dot, fitness.csv and "
        "implementation-<name>.csv; with --replay instead a static folder that plays the "
        "recorded life in a browser (see docs/export.md).",
    )
    add_run_name(export)
    export.add_argument(
        "--generation", type=int, metavar="G", help="export the best of this generation"
    )
    export.add_argument("--out", required=True, metavar="DIR", help="new (or empty) folder")
    add_runs_dir(export)
    export.add_argument(
        "--replay", action="store_true", help="write a static replay folder (viser) instead"
    )
    return export


def cmd_export(args: argparse.Namespace) -> int:
    """Run `gnp-lab export`; a refused export is one `gnp-lab: error:` line."""
    from app.export import ExportError, export_replay, export_run

    path = resolve_run(args.runs_dir, args.run)
    out = Path(args.out)
    if is_task_run(path):  # a Gymnasium task's run: its controller and fitness
        from app.tasks.cli import export

        return export(path, out, args.generation)
    try:
        if args.replay:
            export_replay(path, out, args.generation)
        else:
            export_run(path, out, args.generation)
    except ExportError as error:
        sys.stderr.write(f"gnp-lab: error: {error}\n")
        return EXIT_ERROR
    written = sorted(p.name for p in out.iterdir())
    print(f"{out}: {', '.join(written)}")
    return 0
