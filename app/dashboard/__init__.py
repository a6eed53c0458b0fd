"""The GNP Lab dashboard (viser): `serve(host, port, runs_dir, run)` blocks until Ctrl-C."""

from __future__ import annotations

from pathlib import Path


def serve(host: str, port: int, runs_dir: Path, run: str | None) -> None:
    """Serve the dashboard on http://host:port until interrupted; see `app.dashboard.app`."""
    from app.dashboard.app import serve as _serve  # viser and numba load only when serving

    _serve(host=host, port=port, runs_dir=Path(runs_dir), run=run)


__all__ = ["serve"]
