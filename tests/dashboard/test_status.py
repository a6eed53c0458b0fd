"""The status line: a refusal's warning lasts until its cause ends, and no longer."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest
import viser

from app.dashboard.controls import DashboardInputError
from app.dashboard.status import Status


@pytest.fixture
def status() -> Iterator[Status]:
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        yield Status(server.gui, threading.RLock())
    finally:
        server.stop()


def test_a_warning_ends_when_the_same_control_works_again(status: Status) -> None:
    values = {"sensors": "9"}

    def break_sensors() -> None:  # a control's action: refused while its value is bad
        if values["sensors"] == "9":
            raise DashboardInputError("sensor index 9 is not in 0..7")

    def press_break() -> None:  # a button's callback: a new lambda each click, one code
        status.guarded(None, lambda: break_sensors())

    status.set("loaded run demo")
    press_break()
    assert status.text == "⚠ sensor index 9 is not in 0..7"
    status.guarded(None, lambda: None)  # another control works: the cause is still there
    assert status.text.startswith("⚠")
    values["sensors"] = "2"
    press_break()
    assert status.text == "ready"


def test_an_action_with_words_of_its_own_replaces_a_warning(status: Status) -> None:
    status.guarded(None, lambda: (_ for _ in ()).throw(DashboardInputError("bad")))
    assert status.text == "⚠ bad"
    status.guarded(None, lambda: status.set("loaded run beta"))
    assert status.text == "loaded run beta"
    status.guarded(None, lambda: None)  # nothing to clear now
    assert status.text == "loaded run beta"
