"""`app.workers.share_out`: results in call order whoever computes them, errors surface."""

from __future__ import annotations

import os
import threading
import time

import pytest

from app.workers import WorkerDied, share_out, start_method

PARENT = os.getpid()  # a forked child inherits this value and knows it is not the parent


def square(x: int, count: object) -> int:
    count(x)  # type: ignore[operator]
    time.sleep(0.05)  # long enough that every process gets some calls
    return x * x


def fail_at_three(x: int, count: object) -> int:
    if x == 3:
        raise ValueError(f"no {x}")
    return x


def die_in_a_child(x: int, count: object) -> int:
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
