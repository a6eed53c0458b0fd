"""`app.system.workers`: share_out's results in call order whoever computes them, its progress as it
goes, errors surface with the worker's traceback; the pool's waits end."""

from __future__ import annotations

import os
import threading
import time

import pytest

from app.system.workers import Count, Handler, WorkerDied, WorkerPool, share_out, start_method

PARENT = os.getpid()  # a forked child inherits this value and knows it is not the parent


def square(x: int, count: object) -> int:
    count(x)  # type: ignore[operator]
    time.sleep(0.05)  # long enough that every process gets some calls
    return x * x


def fail_at_three(x: int, _count: object) -> int:
    if x == 3:
        raise ValueError(f"no {x}")
    return x


REPORTS: list[int] = []  # what share_out reported, as this process saw it


def wait_for_the_child(_x: int, count: Count) -> bool:
    """A child counts 100 at once; this process's call counts nothing (0) until it sees that
    count reported (True), giving up after a few seconds (False)."""
    if os.getpid() != PARENT:
        count(100)
        return True
    for _ in range(500):
        count(0)
        if REPORTS and REPORTS[-1] == 100:
            return True
        time.sleep(0.01)
    return False


def die_in_a_child(x: int, _count: object) -> int:
    time.sleep(0.2)
    if os.getpid() != PARENT:
        os._exit(3)
    return x


@pytest.mark.parametrize("method", ["fork", "spawn"])
@pytest.mark.parametrize("workers", [1, 2, 3])
def test_results_come_back_in_call_order_for_any_processes(method: str, workers: int) -> None:
    reports: list[int] = []
    calls = [(x,) for x in range(12)]
    got = share_out(square, calls, workers, reports.append, method=method)
    assert got == [x * x for x in range(12)]
    assert reports == sorted(reports) and reports[-1] <= sum(range(12))


def test_the_childrens_progress_is_reported_while_this_process_works() -> None:
    REPORTS.clear()
    # Two calls, two processes: the child gets call 0, this process call 1 (hand_out first).
    got = share_out(wait_for_the_child, [(0,), (1,)], 2, REPORTS.append, method="fork")
    assert got == [True, True]  # this process's call saw the child's count before returning
    assert REPORTS[-1] == 100 and set(REPORTS) <= {0, 100}


def test_an_exception_in_a_call_is_raised_in_the_caller() -> None:
    with pytest.raises(ValueError, match="no 3"):
        share_out(fail_at_three, [(x,) for x in range(8)], 2, method="fork")


def test_a_child_that_dies_is_reported() -> None:
    with pytest.raises(WorkerDied, match="died"):
        share_out(die_in_a_child, [(x,) for x in range(6)], 2, method="fork")


def test_children_are_forked_only_when_no_other_thread_runs(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(threading, "active_count", lambda: 1)
    assert start_method() == "fork"
    monkeypatch.setattr(threading, "active_count", lambda: 2)
    assert start_method() == "spawn"  # a fork could copy a lock the other thread holds


def raising_worker() -> Handler:
    """A pool worker whose every job fails, inside `fail_at_three`."""
    return fail_at_three


def counting_worker() -> Handler:
    """A pool worker whose job counts every 10 ms for up to 30 s, then answers."""

    def handle(_job: object, count: Count) -> str:
        for _ in range(3000):
            count(1)
            time.sleep(0.01)
        return "done"

    return handle


def test_a_workers_error_carries_the_workers_traceback() -> None:
    with WorkerPool(1, raising_worker, method="fork") as pool:
        pool.send(0, 3)
        with pytest.raises(ValueError, match="no 3") as raised:
            pool.receive()
    notes = "\n".join(getattr(raised.value, "__notes__", []))
    assert "in worker process" in notes
    assert "in fail_at_three" in notes and 'raise ValueError(f"no {x}")' in notes


def test_count_messages_do_not_extend_a_timeout() -> None:
    counted: list[int] = []
    with WorkerPool(1, counting_worker, method="fork") as pool:
        pool.send(0, "count")
        worker, result = pool.receive(0.3, counted.append)
        assert (worker, result) == (-1, None)  # not the answer, 30 s of counts later
        assert pool.busy == [0]


def test_waiting_with_no_job_given_is_an_error_not_a_hang() -> None:
    with WorkerPool(1, counting_worker, method="fork") as pool:
        assert pool.receive(0) == (-1, None)
        with pytest.raises(RuntimeError, match="no worker has a job"):
            pool.receive()
