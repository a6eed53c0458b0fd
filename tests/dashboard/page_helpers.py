"""What the browser tests share: scripts run in the page, and waiting on what it sent."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

TIMEOUT_MS = 120_000
"""How long any state may take to show (generous: the page renders WebGL in software)."""

RECORD_SENT = """
window.gnpLabSent = [];
const postMessage = Worker.prototype.postMessage;
Worker.prototype.postMessage = function (data, ...rest) {
  if (data && data.type === "send") window.gnpLabSent.push(data.message);
  return postMessage.call(this, data, ...rest);
};
"""
"""Records what the page sends the server (viser's client hands it to its websocket worker)."""

SENT_SINCE = """([count, values]) => window.gnpLabSent.slice(count).some(
  (m) => m.type === "GuiUpdateMessage" && values.includes(String(m.updates.value)))"""

HIDE_WEBGL_NOTICE = "#webgl-software-rendering { display: none !important; }"


def sent(page: Any, action: Callable[[], None], *values: str) -> None:
    """Do `action`, then wait until the page has sent the server a GUI update to one of `values`.

    viser's client sends GUI updates through one 50 ms throttle shared by every control and
    keeps only the newest pending message: of three changes within 50 ms (a slow page catching
    up on a loaded machine) the middle one never reaches the server. So each change is seen to
    leave the page before the next is made.
    """
    count = page.evaluate("window.gnpLabSent.length")
    action()
    page.wait_for_function(SENT_SINCE, arg=[count, list(values)], polling=50)
