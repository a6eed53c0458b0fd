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
        self._markdown = gui.add_markdown("**Status:** starting")

    def set(self, text: str) -> None:
        self.text = text
        self._markdown.content = f"**Status:** {text}"

    def guarded(self, client: viser.ClientHandle | None, action: Callable[[], None]) -> None:
        """Run a control's action; a bad value is reported on the page and changes nothing.

        A warning on the status line lasts until the next action that works: one that leaves
        the line as it was clears it, so no ⚠ outlives its cause."""
        try:
            with self.lock:
                before = self.text
                action()
                if self.text == before and before.startswith(WARNING):
                    self.set("ready")
        except REFUSALS as error:
            self.set(f"{WARNING} {error}")
            if client is not None:
                client.add_notification(
                    "Not applied", str(error), color="red", auto_close_seconds=6.0
                )

    def guard(self, action: Callable[[], None]) -> Callable[[viser.GuiEvent[Any]], None]:
        """A GUI callback that runs `action` guarded (and tells the clicking tab if refused)."""

        def callback(event: viser.GuiEvent[Any]) -> None:
            self.guarded(event.client, action)

        return callback
