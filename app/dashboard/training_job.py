"""Training started from the dashboard: `gnp-lab train` in its own process group.

The dashboard never trains in its own process: it runs the CLI exactly as a user would (so the
run file is the same), pauses it with SIGSTOP and resumes it with SIGCONT on its process group,
stops it with SIGTERM, and follows the run file as it is written (SWMR).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Literal

from app.config import RunConfig, to_toml

JobState = Literal["running", "paused", "finished", "failed", "stopped"]


def cli_command() -> list[str]:
    """How to run `gnp-lab` with the interpreter serving the dashboard."""
    script = Path(sys.executable).with_name("gnp-lab")
    if script.exists():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from app.cli import main; sys.exit(main())"]


class TrainingJob:
    """One `gnp-lab train --config FILE --out FILE` subprocess and its lifecycle.

    Args:
        config: the validated run configuration (written to a TOML file the CLI reads).
        out: the run file to create; must not exist.
        workers: worker processes for the CLI (None: its default, one per core).
    """

    def __init__(self, config: RunConfig, out: Path, workers: int | None = None) -> None:
        self.config = config
        self.out = out
        self._dir = tempfile.TemporaryDirectory(prefix="gnp-lab-train-")
        config_path = Path(self._dir.name) / "config.toml"
        config_path.write_text(to_toml(config), encoding="utf-8")
        self._log_path = Path(self._dir.name) / "stderr.log"
        command = [*cli_command(), "train", "--config", str(config_path), "--out", str(out)]
        if workers is not None:
            command += ["--workers", str(workers)]
        self.command = command
        with self._log_path.open("wb") as log:
            self._process = subprocess.Popen(
                command,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=log,
                start_new_session=True,  # its own process group: signals reach its workers too
            )
        self.started = time.monotonic()
        self._paused_at: float | None = None
        self._paused_total = 0.0
        self._stopped = False

    @property
    def pid(self) -> int:
        return self._process.pid

    @property
    def state(self) -> JobState:
        code = self._process.poll()
        if code is None:
            return "paused" if self._paused_at is not None else "running"
        if self._stopped:
            return "stopped"
        return "finished" if code == 0 else "failed"

    @property
    def active(self) -> bool:
        return self._process.poll() is None

    def elapsed(self) -> float:
        """Seconds spent running (pauses excluded)."""
        now = self._paused_at if self._paused_at is not None else time.monotonic()
        return now - self.started - self._paused_total

    def _signal(self, sig: int) -> None:
        if self.active:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self._process.pid, sig)

    def pause(self) -> None:
        if self.active and self._paused_at is None:
            self._signal(signal.SIGSTOP)
            self._paused_at = time.monotonic()

    def resume(self) -> None:
        if self._paused_at is not None:
            self._signal(signal.SIGCONT)
            self._paused_total += time.monotonic() - self._paused_at
            self._paused_at = None

    def stop(self) -> None:
        """Ask the run to stop: SIGTERM to the group (the CLI writes what is complete, exits)."""
        if not self.active:
            return
        self._stopped = True
        self._signal(signal.SIGTERM)
        self.resume()  # a stopped process only handles SIGTERM once continued

    def wait(self, timeout: float = 20.0) -> None:
        """Wait for the process to end; SIGKILL its group if it does not within `timeout`."""
        try:
            self._process.wait(timeout)
        except subprocess.TimeoutExpired:
            self._signal(signal.SIGKILL)
            self._process.wait()

    def error(self) -> str:
        """The last non-empty line the CLI wrote to stderr (its error message on failure)."""
        try:
            text = self._log_path.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return ""
        # tqdm redraws with carriage returns; the last logical line is what matters.
        lines = [line.strip() for line in text.replace("\r", "\n").splitlines() if line.strip()]
        return lines[-1] if lines else ""

    def close(self) -> None:
        """Stop the run if it is still going, wait for it, and remove the temporary files."""
        self.stop()
        self.wait()
        self._dir.cleanup()
