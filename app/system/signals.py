"""Stop signals: Ctrl-C and SIGTERM end the main thread's work as KeyboardInterrupt, so every
`with` and `finally` under way (a pool's close, a temporary file's removal) runs, and the
command says so on one line.

numba's compiler calls back into Python from llvmlite; a KeyboardInterrupt raised there is
swallowed (printed as "Exception ignored") and the compiler may then fail in its place.
`interrupted_by_signals` counts the signals it turned into KeyboardInterrupt, so an error that
follows one is raised as the stop it is, and the swallowed one is not printed; should the
compiler succeed instead, `raise_if_stopped` after it raises the stop it swallowed.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from typing import Any


@contextlib.contextmanager
def handling(sig: int, handler: Any) -> Iterator[None]:
    """`handler` (a function, SIG_IGN or SIG_DFL) for signal `sig` meanwhile, then the previous
    one back. Only the main thread can set handlers: elsewhere signals are left alone."""
    try:
        previous = signal.signal(sig, handler)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(sig, previous if previous is not None else signal.SIG_DFL)


class Stopped(Exception):
    """Work a stop request ended, reporting how far it got (training's `Interrupted`): never
    taken by `interrupted_by_signals` for an error a swallowed interrupt left."""


_signals_heard = 0
"""How many stop signals `raise_interrupt` has turned into KeyboardInterrupt in this process."""

_marks: list[int] = []
"""`_signals_heard` when each `interrupted_by_signals` block under way began, innermost last."""


def raise_interrupt(_signum: int, _frame: object) -> None:
    """A signal handler: SIGTERM (or any) ends the main thread's work as Ctrl-C does, so every
    `with` and `finally` under way (a pool's close, a temporary file's removal) runs."""
    global _signals_heard
    _signals_heard += 1
    raise KeyboardInterrupt


@contextlib.contextmanager
def interrupted_by_signals(handler: Any = raise_interrupt) -> Iterator[None]:
    """Meanwhile Ctrl-C and SIGTERM call `handler` (one that calls `raise_interrupt`) in the
    main thread; an error raised after one of them is raised as KeyboardInterrupt (the user
    asked to stop, not for that error), and a KeyboardInterrupt swallowed in a callback is not
    printed. Elsewhere than in the main thread, which alone gets signals, it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    heard = _signals_heard
    previous_hook = sys.unraisablehook

    def quiet_swallowed(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            return
        if _signals_heard != heard and _compiler_finalizer(unraisable):
            return  # a compilation the signal cut half-way: its half-built objects' finalizers
        previous_hook(unraisable)

    sys.unraisablehook = quiet_swallowed
    _marks.append(heard)
    try:
        with handling(signal.SIGINT, handler), handling(signal.SIGTERM, handler):
            yield
    except Stopped:
        raise
    except Exception as error:
        if _signals_heard == heard:
            raise
        raise KeyboardInterrupt from error
    finally:
        _marks.pop()
        # After a stop signal the process is ending, and the compiler's half-built objects may
        # be collected after this block: the quiet hook stays.
        if _signals_heard == heard:
            sys.unraisablehook = previous_hook


def raise_if_stopped() -> None:
    """KeyboardInterrupt if a stop signal came during the `interrupted_by_signals` block under
    way: its KeyboardInterrupt may have been swallowed by numba's compiler, which then went on.
    Called after work that compiles, before the next (an experiment's warm-up). Elsewhere
    than in the main thread, which alone gets signals and holds such blocks, it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        return
    if _marks and _signals_heard != _marks[-1]:
        raise KeyboardInterrupt


def _compiler_finalizer(unraisable: Any) -> bool:
    """An error in a finalizer of numba's compiler (llvmlite's objects: one whose construction
    a signal cut fails in `__del__`, e.g. `ValueRef` without `_as_parameter_`)."""
    return str(getattr(unraisable.object, "__module__", "")).startswith("llvmlite")


def process_alive(pid: int) -> bool:
    """Whether process `pid` runs (signal 0: no signal sent, only the check)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True
