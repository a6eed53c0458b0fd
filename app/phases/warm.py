"""numba's kernels compiled before a run's work fans out, and that first compile announced.

The first run on a machine compiles the lab's kernels (about half a minute on a quiet core,
minutes on a loaded one); every later run loads them from numba's on-disk cache in a fraction of
a second. `warm_up` lives a tiny run of each controller in this process, so that the kernels are
compiled (or loaded) here, once, before worker processes need them (workers compiling the same
cache at once can race, numba#4807). `CompileWatch` listens to numba's compile events, which fire
only for a real compile, never for a cache load: it says "compiling kernels, first run only" at
the first one, names each kernel as it is compiled and says when they are done; on a warm cache
it says nothing. numba cannot tell in advance how many kernels a run will compile (a kernel's
callees are compiled inside it, on demand), so the progress is a count, not a fraction.

`kernels_warm` tells cheaply (a tiny run, given up at the first compile) whether a run would
compile; the dashboard then compiles in a child process (`python -m app.phases.warm`, the
config's JSON on stdin, one progress line per kernel on stdout) so that its page stays live.
"""

from __future__ import annotations

import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from numba.core import event
from typing_extensions import override

if TYPE_CHECKING:
    from app.settings.config import RunConfig
# The lab's modules are imported inside the functions: importing the simulator compiles small
# kernels (`sim.kernel_cache`), which a `CompileWatch` registered first says too.

COMPILING = "compiling kernels, first run only"
"""What a run says while numba compiles the lab's kernels (the CLI and the dashboard)."""


def warm_up(configs: list[RunConfig]) -> None:
    """Train and implement a tiny run of each config's controller in this process: every
    kernel the lab's tasks call gets compiled (or loaded from numba's cache).

    Raises:
        KeyboardInterrupt: Ctrl-C or SIGTERM, also one that numba's compiler swallowed.
    """
    from app.phases.implementation import implement
    from app.phases.training import train
    from app.settings.loading import build_config
    from app.system.signals import raise_if_stopped

    with tempfile.TemporaryDirectory(prefix="gnp-lab-warm-") as folder:
        for i, config in enumerate(configs):
            brain = config.model_dump(include={"brain"})
            tiny = build_config(
                brain,
                {"training": {"population": 4, "generations": 1, "steps": 2, "noise_sigma": 1,
                              "physics": config.training.physics,
                              "noise_stream": config.training.noise_stream}},
                {"implementation": {"steps": 2, "repeats": 1, "fault_step": 1, "break_count": 1}},
            )  # fmt: skip
            path = Path(folder) / f"warm{i}.h5"
            train(tiny, path, workers=1)
            raise_if_stopped()  # a tiny run's one generation ends with no check of a stop
            implement(path, tiny.implementation, name="warm", workers=1)
            raise_if_stopped()


def kernel_name(dispatcher: Any) -> str:
    """`sim.rays.ir_readings_grid`: a numba dispatcher's module and name."""
    function = dispatcher.py_func
    return f"{function.__module__}.{function.__qualname__}"


class CompileWatch(event.Listener):
    """Says what numba compiles in this thread while registered (a context manager).

    Args:
        say: takes each line (no newline).
        each: also name each kernel as it is compiled (off: only the first and last lines).
    """

    def __init__(self, say: Callable[[str], None], each: bool = True) -> None:
        self._say = say
        self._each = each
        self._thread = threading.get_ident()
        self._depth = 0
        self.compiled = 0  # kernels compiled from Python (their callees inside them not counted)
        self.started: float | None = None
        self._done = False

    def __enter__(self) -> CompileWatch:
        event.register("numba:compile", self)
        _WATCHES.append(self)
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        event.unregister("numba:compile", self)
        _WATCHES.remove(self)
        if kind is None:
            self.finish()

    @override
    def on_start(self, ev: event.Event) -> None:
        if threading.get_ident() != self._thread:
            return
        if self.started is None:
            self.started = time.monotonic()
            self._say(f"{COMPILING} (numba; its cache keeps them for later runs)...")
        self._depth += 1

    def on_end(self, ev: event.Event) -> None:
        if threading.get_ident() != self._thread:
            return
        self._depth -= 1
        if self._depth == 0 and ev.data is not None:
            self.compiled += 1
            if self._each:
                self._say(
                    f"  compiled {kernel_name(ev.data['dispatcher'])} ({self.compiled} so far, "
                    f"{self.seconds:.0f} s)"
                )

    @property
    def seconds(self) -> float:
        """Seconds since the first compile began (0 if none)."""
        return 0.0 if self.started is None else time.monotonic() - self.started

    def finish(self) -> None:
        """Say that the kernels are compiled (once, and only if any was)."""
        if self.started is not None and not self._done:
            self._done = True
            self._say(f"kernels compiled: {self.compiled} in {self.seconds:.0f} s")


_WATCHES: list[CompileWatch] = []
"""The watches registered now (`compiles_done` finishes them)."""


def compiles_done() -> None:
    """Say now, rather than when their command ends, that this thread's watched compiles are
    done (after `warm_up`: what a run compiles, it compiles there)."""
    for watch in _WATCHES:
        if watch._thread == threading.get_ident():
            watch.finish()


class _Cold(Exception):
    """Raised at a compile's start to give up a warm-up as soon as it would compile."""


class _GiveUp(event.Listener):
    def __init__(self) -> None:
        self._thread = threading.get_ident()

    @override
    def on_start(self, ev: event.Event) -> None:
        if threading.get_ident() == self._thread:
            raise _Cold

    def on_end(self, ev: event.Event) -> None:
        pass


def kernels_warm(configs: list[RunConfig]) -> bool:
    """Whether numba's cache holds the kernels of `configs`' runs: their warm-up is lived in
    this thread and given up before its first compile (a fraction of a second when warm)."""
    listener = _GiveUp()
    event.register("numba:compile", listener)
    try:
        warm_up(configs)
    except _Cold:
        return False
    finally:
        event.unregister("numba:compile", listener)
    return True


def main() -> int:
    """`python -m app.phases.warm`: warm up the config read as JSON from stdin, saying what is
    compiled on stdout, one line each."""
    from app.settings.loading import stored_config

    config = stored_config(sys.stdin.read())

    def say(line: str) -> None:
        print(line, flush=True)

    with CompileWatch(say):
        warm_up([config])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
