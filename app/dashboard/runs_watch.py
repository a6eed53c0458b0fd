"""The runs dir, watched: the page's lists of runs follow runs as they are written, added and
removed (by this dashboard or by `gnp-lab` in another terminal), without a *Refresh list*.

A look stats the run files (microseconds each) and reads only those whose stamp changed since
the last look, or that were written too lately for an unchanged stamp to tell (`files.settled`):
a file being written is read once per look until it settles.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from app import store
from app.store.files import Stamp, settled, stamp

UNSETTLED: Stamp = (-1, -1, -1, -1)
"""The stamp of a line to read again at the next look: no file has it."""

TORN_SECONDS = 10.0
"""A file written less than this long ago that cannot be read is taken as caught half-way
through a write (its earlier line stays); older, its error is shown."""


@dataclass
class RunsWatch:
    """The runs dir's `RunSummary` lines, kept between looks."""

    runs_dir: Path
    _lines: dict[Path, tuple[Stamp, store.RunSummary]] = field(default_factory=dict)

    def look(self, again: bool = False) -> list[store.RunSummary] | None:
        """The runs' lines sorted by name, or None when no file changed since the last look.

        `again`: read every file again (*Refresh list*), and return the lines in any case.
        """
        if again:
            self._lines.clear()
        stamps = {path: s for path in store.run_files(self.runs_dir) if (s := stamp(path))}
        if not again and stamps == {path: line[0] for path, line in self._lines.items()}:
            return None
        lines: dict[Path, tuple[Stamp, store.RunSummary]] = {}
        for path, now in stamps.items():
            kept = self._lines.get(path)
            if kept is not None and kept[0] == now:
                lines[path] = kept
                continue
            summary = store.summarize(path)
            if summary.error is not None and time.time() - now[2] / 1e9 < TORN_SECONDS:
                # Perhaps caught half-way through a write: read again at the next look, the
                # earlier line (if any) shown meanwhile.
                lines[path] = (UNSETTLED, summary if kept is None else kept[1])
            else:  # a file still being written is read again until it settles
                lines[path] = (now if settled(now) else UNSETTLED, summary)
        self._lines = lines
        return [summary for _, summary in lines.values()]
