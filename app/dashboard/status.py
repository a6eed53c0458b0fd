"""The page's status line, and the guard every control's callback runs through."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Protocol

import viser

import gnp
import neuro
import sim
from app import store
from app.dashboard.controls import DashboardInputError
from app.phases.live import LiveError

REFUSALS = (
    DashboardInputError,
    LiveError,
    sim.WorldError,
    store.RunFileError,
    gnp.GnpError,
    neuro.NeuroError,
)
"""Errors that mean "this value cannot be used": shown on the page, nothing changes."""
WARNING = "⚠"
"""How the status line starts when something was refused or failed."""


class ProgressBar(Protocol):
    """A progress bar on the page (what `gui.add_progress_bar` returns), by the one thing the
    tabs use; viser does not export its handle's class."""

    @property
    def value(self) -> float: ...


def set_value(handle: Any, value: object) -> None:
    """Assign a GUI input's value (viser's typing marks the setter read-only)."""
    handle.value = value


def _origin(action: Callable[[], None]) -> object:
    """What identifies a control's action across its calls: its code (a lambda made anew for
    each event, or a bound method, has the same code every time)."""
    function = getattr(action, "__func__", action)
    return getattr(function, "__code__", function)


def hex_color(color: tuple[int, int, int]) -> str:
    return "#{:02x}{:02x}{:02x}".format(*color)


class Status:
    """The status line at the top of the control panel.

    Args:
        gui: where to add the line.
        lock: the dashboard's lock; every guarded action holds it, as the live loop does.
    """

    def __init__(self, gui: viser.GuiApi, lock: threading.RLock) -> None:
        self.lock = lock
        self.text = "starting"
        self._warned_by: object = None  # the code of the action whose refusal is on the line
        self._markdown = gui.add_markdown("**Status:** starting")

    def set(self, text: str) -> None:
        self.text = text
        self._markdown.content = f"**Status:** {text}"

    def guarded(self, client: viser.ClientHandle | None, action: Callable[[], None]) -> None:
        """Run a control's action; a bad value is reported on the page and changes nothing.

        A warning lasts until its cause ends: the same control's action works again (one that
        says nothing of its own clears the line), or another action puts its own words there.
        Another control that works silently leaves it: its cause is still there."""
        try:
            with self.lock:
                before = self.text
                action()
                fixed = _origin(action) == self._warned_by
                if self.text == before and before.startswith(WARNING) and fixed:
                    self.set("ready")
        except REFUSALS as error:
            self.set(f"{WARNING} {error}")
            self._warned_by = _origin(action)
            if client is not None:
                client.add_notification(
                    "Not applied", str(error), color="red", auto_close_seconds=6.0
                )

    def guard(self, action: Callable[[], None]) -> Callable[[viser.GuiEvent[Any]], None]:
        """A GUI callback that runs `action` guarded (and tells the clicking tab if refused)."""

        def callback(event: viser.GuiEvent[Any]) -> None:
            self.guarded(event.client, action)

        return callback
