"""Training started from the dashboard: the lab's generation loop in a thread of this process.

The loop is the CLI's (`app.phases.training.train`, so the run file is the same). The robots' lives,
nearly all of its work, go to the lab's worker pool (`app.system.workers`), never to this process;
what runs here, in the job's thread, is the rest of each generation: the evolution (or the
optimiser's step), the HDF5 writes, and at the end the final elite's replay (one robot's
life). The page stays responsive. Pause and resume take effect between generations, stop at
once (the generation under way is dropped, the file keeps every complete one and can be
resumed; the job is "stopping" until its thread ends); the page follows the run file as it is
written (SWMR).

Before the first generation, a run whose kernels numba's cache lacks (the first run on a
machine) compiles them in a child process (`python -m app.phases.warm`), kernel by kernel in
`phase`, so that the page can say so and stay live; on a warm cache that costs a fraction of a
second and says nothing.
"""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Literal

from app.phases.training import Control, Interrupted, train
from app.phases.warm import COMPILING, kernels_warm
from app.settings.config import RunConfig
from app.system.workers import default_workers

JobState = Literal["running", "paused", "stopping", "finished", "failed", "stopped"]
"""A job's state; "stopping": asked to stop, its thread not ended yet (nothing can act)."""


class TrainingJob:
    """One training run in a daemon thread, and its lifecycle.

    Args:
        config: the validated run configuration.
        out: the run file to create; must not exist.
        workers: worker processes (None: one per core; at most one per shard).
    """

    def __init__(self, config: RunConfig, out: Path, workers: int | None = None) -> None:
        self.config = config
        self.out = out
        self._control = Control()
        self._outcome: JobState | None = None
        self._error = ""
        self.started = time.monotonic()
        self._paused_at: float | None = None
        self._paused_total = 0.0
        self.phase = (
            ""  # while numba compiles: what it is doing (`COMPILING`), then that it is done
        )
        self.compiling = False
        self._thread = threading.Thread(
            target=self._run, args=(workers or default_workers(),), name="training", daemon=True
        )
        self._thread.start()

    def _run(self, workers: int) -> None:
        try:
            self._compile()
            train(self.config, self.out, workers=workers, local=False, control=self._control)
            self._outcome = "finished"
        except Interrupted as stop:
            self._error = f"interrupted: {stop}"
            self._outcome = "stopped"
        except Exception as error:  # shown on the page, on one line
            self._error = str(error).splitlines()[0] if str(error) else type(error).__name__
            self._outcome = "failed"

    def _compile(self) -> None:
        """Compile the run's kernels in a child process if numba's cache lacks them, its
        progress in `phase`.

        Raises:
            Interrupted: stopped while compiling (no generation done).
        """
        if kernels_warm([self.config]):
            return
        self.compiling = True
        self.phase = f"{COMPILING}..."
        child = subprocess.Popen(
            [sys.executable, "-m", "app.phases.warm"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        assert child.stdin is not None and child.stdout is not None
        child.stdin.write(self.config.model_dump_json())
        child.stdin.close()
        lines = child.stdout

        def read() -> None:
            for line in lines:
                self.phase = line.strip()

        reader = threading.Thread(target=read, name="compile progress", daemon=True)
        reader.start()
        try:
            while child.poll() is None:
                if self._control.stopping.is_set():
                    child.terminate()
                    child.wait()
                    raise Interrupted(0)
                time.sleep(0.1)
        finally:
            reader.join(5)
            self.compiling = False
        # a child that failed leaves its kernels to the workers: the run says why it fails

    @property
    def state(self) -> JobState:
        if self._thread.is_alive():
            if self._control.stopping.is_set():
                return "stopping"
            return "paused" if self._paused_at is not None else "running"
        return self._outcome or "failed"

    @property
    def held(self) -> bool:
        """Paused and waiting between generations (the one under way when paused is done)."""
        return self._control.held.is_set()

    @property
    def active(self) -> bool:
        return self._thread.is_alive()

    def elapsed(self) -> float:
        """Seconds spent running (pauses excluded)."""
        now = self._paused_at if self._paused_at is not None else time.monotonic()
        return now - self.started - self._paused_total

    def pause(self) -> None:
        """Hold the run before its next generation (not once it is stopping)."""
        if self.state == "running":
            self._control.pause()
            self._paused_at = time.monotonic()

    def resume(self) -> None:
        if self._paused_at is not None:
            self._control.resume()
            self._paused_total += time.monotonic() - self._paused_at
            self._paused_at = None

    def stop(self) -> None:
        """Stop the run: the file keeps every complete generation."""
        if self.active:
            self._control.stop()
            self.resume()

    def wait(self, timeout: float = 20.0) -> None:
        """Wait for the run to end (up to `timeout` s)."""
        self._thread.join(timeout)

    def error(self) -> str:
        """Why the run ended early: its error, or how far it got when stopped."""
        return self._error

    def close(self) -> None:
        """Stop the run if it is still going and wait for it."""
        self.stop()
        self.wait()
