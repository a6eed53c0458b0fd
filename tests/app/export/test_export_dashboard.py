"""The Runs tab's Export and Export replay buttons, through the tab's plain methods."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from app.brains.registry import load_controller
from app.dashboard.controls import DashboardInputError
from app.dashboard.status import set_value
from app.export import ExportError


def test_the_runs_tab_exports_the_loaded_run(finished_run: Path, tmp_path: Path) -> None:
    import viser

    from app.dashboard.app import Dashboard

    shutil.copy(finished_run, tmp_path / "tiny.h5")
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    dashboard = Dashboard(server, tmp_path, "tiny")
    try:
        tab = dashboard.runs
        with dashboard.lock:
            set_value(tab.generation, 1)
            tab.export()
        out = tab.last_export
        assert out is not None and out == tmp_path / "exports" / "tiny-g1"
        assert sorted(p.name for p in out.iterdir()) == [
            "controller.json",
            "fitness.csv",
            "graph.dot",
        ]
        assert dashboard.status.text == f"exported tiny to {out}"
        assert load_controller(out / "controller.json").settings["generation"] == 1
        with dashboard.lock:
            set_value(tab.generation, -1)
            tab.export()
            assert tab.last_export == tmp_path / "exports" / "tiny-g2"
            tab.export(replay=True)  # in the background: the lock is not held meanwhile
            assert dashboard.status.text.startswith("exporting the replay of tiny")
            with pytest.raises(DashboardInputError, match="one at a time"):
                tab.export(replay=True)
        assert tab.exporting is not None
        replay = tab.exporting.result(timeout=120)
        assert replay == tmp_path / "exports" / "tiny-replay" and tab.last_export == replay
        assert {"index.html", "replay.viser"} <= {p.name for p in replay.iterdir()}
        assert dashboard.status.text == f"exported the replay of tiny to {replay}"
        # Again: the replay folder is there; the failure reaches the status line.
        with dashboard.lock:
            tab.export(replay=True)
        with pytest.raises(ExportError):
            tab.exporting.result(timeout=120)
        assert dashboard.status.text == f"⚠ {replay} exists and is not empty; nothing was written"
        # Again: the folder is there; refused on the status line, nothing overwritten.
        before = sorted(p.stat().st_mtime_ns for p in out.iterdir())
        set_value(tab.generation, 1)
        dashboard.status.guarded(None, tab.export)
        assert dashboard.status.text == f"⚠ {out} exists and is not empty; nothing was written"
        assert sorted(p.stat().st_mtime_ns for p in out.iterdir()) == before
        with pytest.raises(DashboardInputError, match="has no generation 7"):
            set_value(tab.generation, 7)
            tab.export()
    finally:
        dashboard.stop()
        server.stop()


def test_a_failed_replay_export_leaves_no_folder(
    finished_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A replay whose writing fails half-way (its elite life unreadable, as a file damaged after
    it was opened would be; a file damaged before is refused when opened): neither the replay's
    folder nor the `exports` folder made for it stays behind (it used to leave `exports/`
    empty)."""
    import viser

    from app.dashboard.app import Dashboard
    from app.export import replay
    from app.store import RunFileError

    def half_written(_reader: object, folder: Path) -> None:
        (folder / "index.html").write_text("<html>")  # something written before the failure
        raise RunFileError("corrupt run file tiny.h5: elite/poses unreadable")

    monkeypatch.setattr(replay, "write_replay", half_written)
    shutil.copy(finished_run, tmp_path / "tiny.h5")
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    dashboard = Dashboard(server, tmp_path, "tiny")
    try:
        tab = dashboard.runs
        with dashboard.lock:
            tab.export(replay=True)
        assert tab.exporting is not None
        with pytest.raises(RunFileError, match="corrupt run file"):
            tab.exporting.result(timeout=120)
        assert dashboard.status.text.startswith("⚠ exporting the replay of tiny: corrupt run file")
        assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny.h5"]
        assert tab.last_export is None
    finally:
        dashboard.stop()
        server.stop()
