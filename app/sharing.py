"""Calls of one function shared out over this process and a few child processes.

The calling process works too (it is warm: modules imported, numba kernels loaded), and every
process takes the next call as soon as it is free, so a child that starts late or a slow call
costs little. Children are forked when that is safe (no other thread in this process: nothing
can hold a lock across the fork), which spares each one a fresh interpreter's imports, else
spawned. Results come back in call order, whoever computed them, so they do not depend on the
number of processes.
"""

from __future__ import annotations

import multiprocessing
import pickle
import queue
import threading
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.process import BaseProcess
from typing import Any

Count = Callable[[int], None]


class WorkerDied(RuntimeError):
    """A child process ended without returning the results of the calls it took."""


def start_method() -> str:
    """`fork` where it is available and this process runs no other thread, else `spawn`."""
    if "fork" in multiprocessing.get_all_start_methods() and threading.active_count() == 1:
        return "fork"
    return "spawn"


def share_out(
    function: Callable[..., Any],
    calls: Sequence[tuple[Any, ...]],
    workers: int,
    report: Callable[[int], None] = lambda done: None,
    method: str | None = None,
) -> list[Any]:
    """`[function(*call, count) for call in calls]`, on this process and `workers` − 1 children.

    Args:
        function: A module-level function (a spawned child imports it); its last argument is
            `count`, to call with each amount of work done.
        calls: Every call's other arguments (picklable, for a spawned child).
        workers: Processes in all, this one included.
        report: Called in this process with the work done so far, by every process.
        method: The children's start method (default: `start_method()`).

    Raises:
        WorkerDied: a child process died; an exception in a call is raised again here.
    """
    context: Any = multiprocessing.get_context(method or start_method())  # typeshed: BaseContext
    tally = context.Value("q", 0)
    taken = context.Value("q", 0)
    results = context.Queue()
    children = [
        context.Process(target=_child, args=(function, calls, taken, tally, results), daemon=True)
        for _ in range(min(workers, len(calls)) - 1)
    ]
    for child in children:
        child.start()
    out: dict[int, Any] = {}

    def count(done: int) -> None:
        report(_add(tally, done))

    try:
        while (i := _take(taken, len(calls))) is not None:
            out[i] = function(*calls[i], count)
            _collect(results, out, wait=0.0)
        while len(out) < len(calls):
            _collect(results, out, wait=0.1)
            report(tally.value)
            if len(out) < len(calls) and any(_died(c) for c in children):
                _collect(results, out, wait=0.5)  # what a child sent just before it died
                if len(out) < len(calls):
                    codes = [c.exitcode for c in children]
                    raise WorkerDied(f"a worker process died (exit codes {codes})")
    finally:
        for child in children:
            if len(out) < len(calls):
                child.terminate()
            child.join()
        results.close()
    return [out[i] for i in range(len(calls))]


def _take(taken: Any, n: int) -> int | None:
    with taken.get_lock():
        i = int(taken.value)
        if i >= n:
            return None
        taken.value = i + 1
    return i


def _add(tally: Any, done: int) -> int:
    with tally.get_lock():
        tally.value += done
        return int(tally.value)


def _died(child: BaseProcess) -> bool:
    return child.exitcode is not None and child.exitcode != 0


def _collect(results: Any, out: dict[int, Any], wait: float) -> None:
    """Move every result that has arrived (waiting up to `wait` s for the first) into out."""
    while True:
        try:
            i, value, error = results.get(timeout=wait) if wait else results.get_nowait()
        except queue.Empty:
            return
        if error is not None:
            raise error
        out[i] = value
        wait = 0.0


def _child(
    function: Callable[..., Any],
    calls: Sequence[tuple[Any, ...]],
    taken: Any,
    tally: Any,
    results: Any,
) -> None:
    """A child's loop: take the next call, send back its result (or its exception)."""

    def count(done: int) -> None:
        _add(tally, done)

    while (i := _take(taken, len(calls))) is not None:
        try:
            results.put((i, function(*calls[i], count), None))
        except BaseException as error:  # sent to the parent, raised there
            try:
                pickle.dumps(error)
                sent: BaseException = error
            except Exception:  # an exception that does not pickle: its traceback does
                sent = RuntimeError(traceback.format_exc())
            results.put((i, None, sent))
            return
