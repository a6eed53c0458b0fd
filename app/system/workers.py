"""The lab's one worker pool: persistent child processes that serve jobs over pipes.

Every phase that works in more than one process goes through here (training's shards, the
implementation's trial worlds, the dashboard's implementation), so the start method, the
workers' signal handling and the shutdown are decided once:

- Start method: `fork` where it is available and this process runs no other thread (nothing
  can hold a lock across the fork, and a child is spared a fresh interpreter's imports), else
  `spawn`.
- Signals: Ctrl-C and SIGTERM reach the whole process group; workers ignore them, the parent
  decides and stops its workers itself.
- A parent's death: a worker ends within `PARENT_WATCH` seconds of it, however its parent
  died (SIGKILL included): a thread of its own watches its parent id. The thread needs the
  GIL, so a worker in a compiled call ends when the call returns; and a spawned worker starts
  watching once it has imported what its job needs (about a second of CPU). A forked worker
  also closes every pipe end it inherited but its own, so a worker waiting on its pipe sees
  it close at once.
- Shutdown: `close` asks each worker to end, waits a little (not at all when interrupted
  mid-job, or for a worker never given a job: their results are not wanted) and kills what
  is left.

A worker builds its state once (`setup(*args)`, in the child) and then answers each job with
`state(job, count)`; `count(n)` reports work done as it goes. Which job goes to which worker is
the caller's choice, so results do not depend on the number of workers.

Bulk data need not go through the pipes: `SharedArrays` are named numpy arrays in one
shared-memory block that the parent creates (and alone unlinks) and the workers attach to by
name, so a job can be a few numbers saying which rows to read and write.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import pickle
import secrets
import signal
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from multiprocessing.shared_memory import SharedMemory
from pathlib import Path
from typing import Any

import numpy as np

from app.system.signals import process_alive

Count = Callable[[int], None]
#: What a worker's `setup` returns: answers one job, reporting work done with `count`.
Handler = Callable[[Any, Count], Any]


class WorkerDied(RuntimeError):
    """A worker process ended without answering the job it had."""


def start_method() -> str:
    """`fork` where it is available and this process runs no other thread, else `spawn`."""
    if "fork" in multiprocessing.get_all_start_methods() and threading.active_count() == 1:
        return "fork"
    return "spawn"


def default_workers() -> int:
    """One worker per core."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _sendable(error: BaseException) -> BaseException:
    """`error` if it pickles, else a RuntimeError carrying its traceback."""
    try:
        pickle.dumps(error)
    except Exception:
        return RuntimeError(traceback.format_exc())
    return error


PARENT_WATCH = 0.2
"""Seconds between a worker's looks at whether its parent still lives."""


def watch_parent(parent: int) -> None:
    """End this process (at once, as SIGKILL would) when process `parent` is no longer its
    parent: it died and this one was handed to another. Looked at from a daemon thread every
    `PARENT_WATCH` seconds, so it works whatever the main thread is doing, on any OS.

    Not PR_SET_PDEATHSIG: that fires when the *thread* that started the child ends, and the
    dashboard starts workers from threads that end before their workers do.
    """

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_WATCH)
        os._exit(1)

    threading.Thread(target=watch, name="watch-parent", daemon=True).start()


def _serve(
    conn: Connection,
    setup: Callable[..., Handler],
    args: tuple[Any, ...],
    parent: int,
    inherited: Sequence[Connection] = (),
) -> None:
    """A worker's loop: build the state, then answer each job `conn` brings until None.

    `parent` is the pool's process id; `inherited`, the pool's ends of the pipes (a forked
    child has them all, its own pipe's included), closed here.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    for end in inherited:
        end.close()
    watch_parent(parent)
    try:
        handle = setup(*args)

        def count(done: int) -> None:
            conn.send(("count", done))

        while (job := conn.recv()) is not None:
            try:
                conn.send(("done", handle(job, count)))
            except Exception as error:  # sent to the parent, raised there
                # The parent re-raises it with its own traceback: the note (notes survive
                # pickling) says where in this process it happened.
                error.add_note(f"in worker process {os.getpid()}:\n{traceback.format_exc()}")
                conn.send(("error", _sendable(error)))
    except (EOFError, BrokenPipeError, KeyboardInterrupt):
        pass


class WorkerPool:
    """`workers` persistent child processes, each with its state from `setup(*args)`.

    Args:
        workers: how many children.
        setup: a module-level function (a spawned child imports it), called once in each child;
            returns the handler of that child's jobs.
        args: `setup`'s arguments (picklable).
        method: the start method (default: `start_method()`).
    """

    def __init__(
        self,
        workers: int,
        setup: Callable[..., Handler],
        args: tuple[Any, ...] = (),
        method: str | None = None,
    ) -> None:
        context: Any = multiprocessing.get_context(method or start_method())
        forked = context.get_start_method() == "fork"
        self._conns: list[Connection] = []
        self._procs: list[Any] = []
        self.pending: dict[int, int] = {}  # worker → jobs given and not yet answered
        try:
            for _ in range(workers):
                parent, child = context.Pipe()
                # A forked child inherits this process's ends of every pipe so far (its own
                # too): it closes them, else no worker would see its pipe close.
                inherited = [*self._conns, parent] if forked else []
                proc = context.Process(
                    target=_serve,
                    args=(child, setup, args, os.getpid(), inherited),
                    daemon=True,
                )
                proc.start()
                child.close()
                self._conns.append(parent)
                self._procs.append(proc)
        except BaseException:
            self.close()
            raise

    @property
    def size(self) -> int:
        return len(self._procs)

    @property
    def busy(self) -> list[int]:
        """The workers with jobs to answer."""
        return [worker for worker, n in sorted(self.pending.items()) if n]

    def send(self, worker: int, job: Any) -> None:
        """Give `worker` a job (queued behind the ones it has; answered in order)."""
        try:
            self._conns[worker].send(job)
        except (BrokenPipeError, OSError):
            raise self._died() from None
        self.pending[worker] = self.pending.get(worker, 0) + 1

    def receive(self, timeout: float | None = None, count: Count | None = None) -> tuple[int, Any]:
        """The next answer of a busy worker as (worker, result), waiting up to `timeout` s in
        all (-1, None: no answer by then). Counts reported meanwhile go to `count`.

        Raises:
            WorkerDied: a busy worker died; an exception in a job is raised again here.
            RuntimeError: no worker has a job and `timeout` is None (it would wait forever).
        """
        # One deadline for the whole call: count messages must not restart the wait.
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            busy = self.busy
            if not busy and deadline is None:
                raise RuntimeError("waiting for an answer, but no worker has a job")
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            ready = wait([self._conns[i] for i in busy], left)
            if not ready:
                return -1, None
            for conn in ready:
                assert isinstance(conn, Connection)
                worker = self._conns.index(conn)
                try:
                    kind, value = conn.recv()
                except (EOFError, OSError):
                    raise self._died() from None
                if kind == "count":
                    if count is not None:
                        count(value)
                    continue
                self.pending[worker] -= 1
                if isinstance(value, BaseException) and kind == "error":
                    raise value
                return worker, value

    def map(self, jobs: Sequence[Any], cancelled: Callable[[], bool] | None = None) -> list[Any]:
        """Job i to worker i (all at once); their results in that order.

        Raises:
            KeyboardInterrupt: `cancelled()` turned true meanwhile (looked at a few times a
                second); the jobs under way are dropped at `close`.
        """
        for i, job in enumerate(jobs):
            self.send(i, job)
        answers = dict(self.gather(len(jobs), cancelled))  # one job each
        return [answers[i] for i in range(len(jobs))]

    def gather(self, n: int, cancelled: Callable[[], bool] | None = None) -> list[tuple[int, Any]]:
        """The next `n` answers, as (worker, result) in the order they came: `map`'s second
        half, for a caller with work of its own to do while its jobs are under way.

        Raises:
            KeyboardInterrupt: as `map`.
        """
        out: list[tuple[int, Any]] = []
        while len(out) < n:
            worker, result = self.receive(None if cancelled is None else 0.2)
            if worker >= 0:
                out.append((worker, result))
            elif cancelled is not None and cancelled():
                raise KeyboardInterrupt
        return out

    def _died(self) -> WorkerDied:
        for proc in self._procs:
            proc.join(timeout=0.5 if proc.is_alive() else 0)
        codes = [proc.exitcode for proc in self._procs]
        return WorkerDied(f"a worker process died (exit codes {codes})")

    def close(self) -> None:
        """End every worker: at once if one was mid-job (its result is not wanted) or was never
        given a job (it may still be building a state nobody wants: a run that fails to start
        does not wait for it), else after it finishes its loop; what does not end is killed."""
        interrupted = bool(self.busy)
        for conn in self._conns:
            with contextlib.suppress(BrokenPipeError, OSError):
                conn.send(None)
        for worker, proc in enumerate(self._procs):
            proc.join(timeout=0 if interrupted or worker not in self.pending else 5)
            if proc.is_alive():
                proc.kill()
                proc.join()
        for conn in self._conns:
            conn.close()
        self._conns, self._procs = [], []
        self.pending.clear()

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --- arrays in shared memory ----------------------------------------------------------------

#: What `SharedArrays` holds: each array's name, shape and dtype (a dtype string or descr).
Layout = dict[str, tuple[tuple[int, ...], Any]]

_ALIGN = 64  # each array starts on a cache line (a GNP population's records must)


def _offsets(layout: Layout) -> tuple[dict[str, int], int]:
    offsets, end = {}, 0
    for name, (shape, dtype) in layout.items():
        end = -(-end // _ALIGN) * _ALIGN
        offsets[name] = end
        end += int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize
    return offsets, max(end, 1)


SHARED_PREFIX = "gnplab_"
"""How the names of the lab's shared blocks start; then the creator's process id."""
SHARED_FOLDER = Path("/dev/shm")


def sweep_shared() -> list[str]:
    """Unlink the lab's shared blocks whose creator no longer runs; their names."""
    swept = []
    with contextlib.suppress(OSError):
        for path in SHARED_FOLDER.glob(f"{SHARED_PREFIX}*"):
            pid = path.name[len(SHARED_PREFIX) :].partition("_")[0]
            if pid.isdigit() and not process_alive(int(pid)):
                with contextlib.suppress(OSError):
                    path.unlink()
                    swept.append(path.name)
    return swept


class SharedArrays:
    """Named numpy arrays in one shared-memory block (`/dev/shm` on Linux).

    The parent `create`s the block and passes `spec` (its name and layout: a short, picklable
    tuple) to its workers, which `attach`. Only the creator unlinks the block (`close`); it is
    also registered with multiprocessing's resource tracker, which unlinks it should the
    creator be killed before it could. Workers attach untracked: a worker ending does not
    unlink, nor warn of, a block it does not own.
    """

    def __init__(self, memory: SharedMemory, layout: Layout, owner: bool) -> None:
        self._memory, self._layout, self._owner = memory, layout, owner
        offsets, _ = _offsets(layout)
        self.arrays: dict[str, np.ndarray] = {
            name: np.ndarray(shape, np.dtype(dtype), memory.buf, offsets[name])
            for name, (shape, dtype) in layout.items()
        }

    @classmethod
    def create(cls, layout: Layout) -> SharedArrays:
        """A new block holding zeroed arrays of `layout`, named after this process.

        First unlinks the blocks of processes that no longer run: a run killed with its whole
        process group (SIGKILL to `killpg`) takes the resource tracker with it, and its block
        would stay in `/dev/shm` until the machine restarts.
        """
        sweep_shared()
        name = f"{SHARED_PREFIX}{os.getpid()}_{secrets.token_hex(4)}"
        memory = SharedMemory(name, create=True, size=_offsets(layout)[1])
        return cls(memory, layout, owner=True)

    @classmethod
    def attach(cls, spec: tuple[str, Layout]) -> SharedArrays:
        """The block `spec` names (see `spec`), as a worker sees it."""
        name, layout = spec
        return cls(SharedMemory(name, track=False), layout, owner=False)

    @property
    def spec(self) -> tuple[str, Layout]:
        """What a worker needs to `attach`: the block's name and layout."""
        return self._memory.name, self._layout

    def __getitem__(self, name: str) -> np.ndarray:
        return self.arrays[name]

    def close(self) -> None:
        """Drop this process's mapping; the owner also unlinks the block (idempotent)."""
        self.arrays = {}
        with contextlib.suppress(BufferError):  # a view still held elsewhere: unmapped at exit
            self._memory.close()
        if self._owner:
            self._owner = False
            with contextlib.suppress(FileNotFoundError):
                self._memory.unlink()


# --- calls of one function, shared out over this process and the pool -------------------------


def _calls_of(function: Callable[..., Any]) -> Handler:
    """A share_out worker's state: `function(*call, count)` for each call it is given."""
    return lambda call, count: function(*call, count)


def share_out(
    function: Callable[..., Any],
    calls: Sequence[tuple[Any, ...]],
    workers: int,
    report: Count = lambda _done: None,
    method: str | None = None,
) -> list[Any]:
    """`[function(*call, count) for call in calls]`, on this process and `workers` − 1 children.

    The calling process works too (it is warm: modules imported, numba kernels loaded), and
    every process takes the next call as soon as it is free, so a child that starts late or a
    slow call costs little. Results come back in call order, whoever computed them.

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
    total = 0

    def count(done: int) -> None:
        nonlocal total
        total += done
        report(total)

    out: dict[int, Any] = {}
    children = min(workers, len(calls)) - 1
    if children <= 0:
        return [function(*call, count) for call in calls]
    with WorkerPool(children, _calls_of, (function,), method) as helpers:
        given: dict[int, list[int]] = {w: [] for w in range(helpers.size)}  # calls, in order
        taken = 0

        def hand_out() -> None:
            # A child gets a second call queued while plenty are left, so that it goes on
            # while this process is busy with its own; near the end, one at a time.
            nonlocal taken
            for worker in range(helpers.size):
                depth = 2 if len(calls) - taken > helpers.size + 1 else 1
                while len(given[worker]) < depth and taken < len(calls):
                    helpers.send(worker, calls[taken])
                    given[worker].append(taken)
                    taken += 1

        def collect(timeout: float | None) -> None:
            worker, result = helpers.receive(timeout, count)
            while worker >= 0:
                out[given[worker].pop(0)] = result
                worker, result = helpers.receive(0, count)

        def own(done: int) -> None:
            # This process's calls count through here: the children's counts and answers
            # are taken in meanwhile (else progress would stall until the call returns), and
            # a child that finished gets its next call at once.
            count(done)
            collect(0)
            hand_out()

        hand_out()
        while taken < len(calls):
            mine = taken
            taken += 1
            out[mine] = function(*calls[mine], own)
            collect(0)
            hand_out()
        while helpers.busy:
            collect(None)
    return [out[i] for i in range(len(calls))]
