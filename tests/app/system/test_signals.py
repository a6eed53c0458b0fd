"""`app.system.signals.interrupted_by_signals`: Ctrl-C and SIGTERM stop the main thread's work
as KeyboardInterrupt, also when numba's compiler swallows that KeyboardInterrupt (in an llvmlite
callback) and fails in its place; errors that no signal preceded pass through unchanged."""

from __future__ import annotations

import contextlib
import signal

import pytest

from app.system.signals import Stopped, interrupted_by_signals, raise_if_stopped, raise_interrupt


def swallowed(sig: int) -> None:
    """What numba's compiler does with a signal's KeyboardInterrupt, in the worst case."""
    with contextlib.suppress(KeyboardInterrupt):
        signal.raise_signal(sig)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_raises_keyboard_interrupt_and_the_handlers_come_back(sig: int) -> None:
    before = signal.getsignal(sig)
    with pytest.raises(KeyboardInterrupt), interrupted_by_signals():
        signal.raise_signal(sig)
    assert signal.getsignal(sig) is before


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_error_left_by_a_swallowed_interrupt_is_the_interrupt(sig: int) -> None:
    left = RuntimeError("no compiled object yet for <Library 'wall_distances'>")
    with pytest.raises(KeyboardInterrupt) as stop, interrupted_by_signals():
        swallowed(sig)
        raise left
    assert stop.value.__cause__ is left  # kept, for whoever debugs it


def test_an_error_no_signal_preceded_in_the_block_is_raised_as_it_is() -> None:
    with pytest.raises(KeyboardInterrupt), interrupted_by_signals():
        swallowed(signal.SIGTERM)
        raise ValueError("left by the stop")
    # A later block (a new command in the same process) heard no signal of its own.
    with pytest.raises(ValueError, match="a real error"), interrupted_by_signals():
        raise ValueError("a real error")


def test_nested_blocks_each_see_the_signal() -> None:
    """The CLI's block holds an experiment's, which holds training's: the innermost converts."""
    with pytest.raises(KeyboardInterrupt) as stop, interrupted_by_signals():  # noqa: SIM117
        with interrupted_by_signals():
            swallowed(signal.SIGTERM)
            raise OSError("a compiler's half-written cache")
    assert isinstance(stop.value.__cause__, OSError)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_swallowed_interrupt_that_left_no_error_stops_at_the_next_check(sig: int) -> None:
    """The compiler went on as if nothing happened (seen in CI: a SIGTERM in an experiment's
    warm-up, and the experiment then ran to its end): the next `raise_if_stopped` stops."""
    went_on = False
    with pytest.raises(KeyboardInterrupt), interrupted_by_signals():
        raise_if_stopped()  # nothing heard yet: nothing raised
        swallowed(sig)
        raise_if_stopped()
        went_on = True
    assert not went_on


def test_a_check_hears_only_the_signals_of_its_own_block() -> None:
    """A stop heard by an earlier block (an earlier command in the same process) is not heard
    again; outside any block there is nothing to check."""
    with contextlib.suppress(KeyboardInterrupt), interrupted_by_signals():
        swallowed(signal.SIGTERM)
        raise_if_stopped()
    raise_if_stopped()
    with interrupted_by_signals():
        raise_if_stopped()
    with pytest.raises(KeyboardInterrupt), interrupted_by_signals():
        with interrupted_by_signals():  # the inner block ends; the stop is the outer's too
            swallowed(signal.SIGTERM)
        raise_if_stopped()


def test_a_check_off_the_main_thread_is_not_stopped_by_the_main_threads_signal() -> None:
    """A worker thread's warm-up (an in-process Dask worker's) is not the main thread's work:
    the main thread's stop ends its own block, not the thread's."""
    import threading

    raised: list[BaseException] = []

    def check() -> None:
        try:
            raise_if_stopped()
        except BaseException as error:
            raised.append(error)

    with pytest.raises(KeyboardInterrupt), interrupted_by_signals():
        swallowed(signal.SIGTERM)
        thread = threading.Thread(target=check)
        thread.start()
        thread.join()
        raise_if_stopped()  # the main thread's own check: stopped
    assert raised == []


def test_a_stop_reported_as_such_is_left_as_it_is() -> None:
    """Training stopped by the signal says how far it got (`Interrupted`): that report stays."""

    class Interrupted(Stopped):
        pass

    with pytest.raises(Interrupted), interrupted_by_signals():
        try:
            signal.raise_signal(signal.SIGTERM)
        except KeyboardInterrupt:
            raise Interrupted("stopped after 3 complete generation(s)") from None


def test_off_the_main_thread_it_leaves_errors_and_hooks_alone() -> None:
    """A dashboard's training thread: no signal reaches it, and the process's hook is not its."""
    import sys
    import threading

    hook = sys.unraisablehook
    seen: list[BaseException] = []

    def work() -> None:
        try:
            with interrupted_by_signals():
                assert sys.unraisablehook is hook
                raise ValueError("a thread's own error")
        except BaseException as error:
            seen.append(error)

    with contextlib.suppress(KeyboardInterrupt):
        raise_interrupt(signal.SIGTERM, None)  # a signal the main thread heard
    thread = threading.Thread(target=work)
    thread.start()
    thread.join()
    assert [type(error) for error in seen] == [ValueError]


def test_after_a_stop_signal_a_cut_compilations_finalizer_errors_are_not_printed() -> None:
    """A SIGTERM inside numba's compile can leave llvmlite objects half-built, whose `__del__`
    then fails when collected, even after the command said its one line: not passed on to the
    process's hook (which prints it); any other finalizer's error still is."""
    import gc
    import sys

    class Compiler:
        def __del__(self) -> None:
            raise AttributeError("'ValueRef' object has no attribute '_as_parameter_'")

    class Other:
        def __del__(self) -> None:
            raise AttributeError("a finalizer of our own")

    Compiler.__del__.__module__ = "llvmlite.binding.ffi"
    passed_on: list[str] = []
    hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: passed_on.append(str(unraisable.exc_value))
    try:
        with contextlib.suppress(KeyboardInterrupt), interrupted_by_signals():
            signal.raise_signal(signal.SIGTERM)
        compiler, other = Compiler(), Other()
        del compiler, other
        gc.collect()
    finally:
        sys.unraisablehook = hook
    assert passed_on == ["a finalizer of our own"]
