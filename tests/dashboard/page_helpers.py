"""What the dashboard tests share: a dashboard in this process, waiting on its state, scripts
run in the page, and waiting on what the page sent."""

from __future__ import annotations

import os
import re
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

DEMO = Path(__file__).resolve().parents[2] / "saved_runs" / "demo.h5"
"""The shipped demo run."""

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


def viewport() -> dict[str, int]:
    """1280x720 by default (software WebGL is slow); GNP_LAB_VIEWPORT=1600x900 for docs."""
    width, height = os.environ.get("GNP_LAB_VIEWPORT", "1280x720").split("x")
    return {"width": int(width), "height": int(height)}


def open_page(browser: Any, url: str, size: dict[str, int] | None = None) -> Any:
    """A new page on the dashboard at `url` (`size`: its viewport, default `viewport()`),
    recording what it sends, once it shows its status."""
    page = browser.new_page(viewport=size or viewport())
    page.set_default_timeout(TIMEOUT_MS)
    page.add_init_script(RECORD_SENT)
    page.goto(url)
    page.add_style_tag(content=HIDE_WEBGL_NOTICE)
    page.get_by_text("Status:").first.wait_for()
    return page


def field(page: Any, label: str) -> Any:
    """The input on the row of a GUI control's label (viser breaks long labels with <wbr> and
    does not always link the two)."""
    row = "ancestor::div[contains(@class, 'mantine-Flex-root')][1]"
    return page.locator(f'xpath=//label[normalize-space(.)="{label}"]/{row}//input').first


def choose(page: Any, label: str, option: str) -> None:
    """Pick `option` in the dropdown labelled `label`."""
    box = field(page, label)
    if box.input_value() == option:
        return  # picking the chosen option again would unset it

    def pick() -> None:
        box.click()
        page.get_by_role("option", name=option, exact=True).click()

    sent(page, pick, option)


def type_into(page: Any, label: str, value: str) -> None:
    """Type `value` into the input labelled `label`."""
    box = field(page, label)
    if box.input_value() == value:
        return  # nothing changes, nothing is sent

    def type_value() -> None:
        box.fill(value)
        box.press("Enter")
        box.blur()

    sent(page, type_value, value)


def press(page: Any, button: str) -> None:
    """Click a button (alone it sends True, in a group its name)."""
    sent(page, page.get_by_role("button", name=button).click, button, "true")


LINE_TEXT = """(prefix) => {
  const line = [...document.querySelectorAll("p")].find((p) => p.innerText.startsWith(prefix));
  return line ? line.innerText : "(no such line)";
}"""

LINE_MATCH = """([prefix, pattern]) => {
  const line = [...document.querySelectorAll("p")].find((p) => p.innerText.startsWith(prefix));
  const match = line && new RegExp(pattern).exec(line.innerText);
  return match ? match[0] : null;
}"""


def wait_for_line(page: Any, prefix: str, pattern: str) -> re.Match[str]:
    """Wait until the page's paragraph starting with `prefix` matches `pattern` (a JavaScript
    RegExp, same syntax here); the match is the text as it was when it matched."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    try:
        found = page.wait_for_function(LINE_MATCH, arg=[prefix, pattern], polling=100)
    except PlaywrightTimeout:
        text = page.evaluate(LINE_TEXT, prefix)  # the paragraph LINE_MATCH read, whole
        raise AssertionError(f"{prefix!r} never matched {pattern!r}; last: {text}") from None
    match = re.search(pattern, found.json_value())
    assert match is not None
    return match


@contextmanager
def dashboard_in_process(runs_dir: Path, run: str | None = None) -> Iterator[Any]:
    """A `Dashboard` of `runs_dir` (showing `run`) on a viser server of its own at a free port,
    in this process, so that a test reads the scene from the server's own handles; stopped
    after."""
    import viser

    from app.dashboard.app import Dashboard

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    board = Dashboard(server, runs_dir, run)
    try:
        yield board
    finally:
        board.stop()
        server.stop()


def until(condition: Callable[[], bool], seconds: float = 120.0) -> None:
    """Wait until `condition` holds (polled every 50 ms)."""
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, "the server never reached the state"
        time.sleep(0.05)


def until_tab(board: Any, condition: Callable[[], bool], seconds: float = 120.0) -> None:
    """Wait until `condition` holds, letting the Experiments tab put background work on the
    page first each time (under the dashboard's lock)."""

    def followed() -> bool:
        with board.lock:
            board.experiments.follow()
            return condition()

    until(followed, seconds)
