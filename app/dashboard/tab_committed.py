"""The Experiments tab's committed reports: the thesis's answers and every report in the
checkout's docs/experiments, shown with no run files (a fresh clone shows the lab's answers).

The reports are read (`committed.read_shelf`) and a claim's picture drawn in a background
thread; callbacks only pick what to show. `choose(experiment, scale)` is how the tab's local
runs offer the committed report of the same experiment and scale beside them.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import viser

from app.dashboard import committed_view as cv
from app.dashboard.committed import (
    DOCS,
    CommittedError,
    CommittedReport,
    Shelf,
    read_shelf,
    shelf_signature,
)
from app.dashboard.controls import DashboardInputError
from app.dashboard.status import Status, set_value
from app.dashboard.tab_runs import set_options

BLANK = np.full((1, 1, 4), 255, dtype=np.uint8)

Read = tuple[Shelf, str, str]  # the shelf, its reports table, its answers table
_READ: dict[tuple[Path, tuple[Any, ...]], tuple[Shelf, str]] = {}


def read_once(root: Path) -> tuple[Shelf, str]:
    """The shelf and its answers table, read again only when a report file changed (every
    dashboard of a process shares them: the answers load every shipped spec)."""
    key = (root, shelf_signature(root))
    if key not in _READ:
        shelf = read_shelf(root)
        _READ.clear()
        _READ[key] = (shelf, cv.answers_table(shelf))
    return _READ[key]


@dataclass
class CommittedSection:
    """The committed reports' handles, the shelf read, and the report and claim shown."""

    status: Status
    reports: viser.GuiMarkdownHandle
    answers: viser.GuiMarkdownHandle
    report: viser.GuiDropdownHandle[str]
    header: viser.GuiMarkdownHandle
    claims: viser.GuiMarkdownHandle
    claim: viser.GuiDropdownHandle[str]
    image: viser.GuiImageHandle
    caption: viser.GuiMarkdownHandle
    shelf: Shelf = field(default_factory=Shelf)
    pages: cv.PageServer | None = None
    _pool: ThreadPoolExecutor = field(
        default_factory=lambda: ThreadPoolExecutor(1, thread_name_prefix="committed-reports")
    )
    _read: Future[Read] | None = None
    _picture: Future[tuple[str, str, np.ndarray, str]] | None = None
    _closed: bool = False

    def read(self) -> None:
        """Read the checkout's reports (in the background)."""
        if not self._closed and (self._read is None or self._read.done()):
            self._read = self._pool.submit(self._read_shelf)
            self._read.add_done_callback(self._landed)

    def _read_shelf(self) -> Read:
        shelf, answers = read_once(DOCS)
        if self.pages is None and not shelf.missing and not self._closed:
            self.pages = cv.PageServer(DOCS)
        url = self.pages.url if self.pages else ""
        return shelf, cv.reports_table(shelf, url), answers

    def choose(self, experiment: str, scale: str) -> None:
        """Show the committed report of `experiment` at `scale`, if there is one."""
        found = self.shelf.of(experiment, scale)
        if found is not None and self.report.value != found.name:
            set_value(self.report, found.name)
            self.show_report()

    def chosen(self) -> CommittedReport | None:
        return self.shelf.find(self.report.value)

    def show_report(self) -> None:
        """The chosen report's header, claims and its first claim's picture."""
        report = self.chosen()
        if report is None:
            self.header.content = self.claims.content = ""
            set_options(self.claim, [], cv.NO_CLAIMS)
            self._clear_picture()
            return
        page = self.pages.page(report) if self.pages else ""
        self.header.content = cv.header(report, page)
        self.claims.content = cv.claims_tables(report)
        set_options(self.claim, [c.name for c in report.report.comparisons], cv.NO_CLAIMS)
        self.show_claim()

    def show_claim(self) -> None:
        """Draw the chosen claim's runs (in the background)."""
        report = self.chosen()
        if report is None or self.claim.value == cv.NO_CLAIMS or self._closed:
            self._clear_picture()
            return
        try:
            claim = report.claim(self.claim.value)
        except CommittedError as error:
            raise DashboardInputError(str(error)) from None
        self._picture = self._pool.submit(
            lambda: (report.name, claim.name, cv.spread_image(report, claim),
                     cv.spread_caption(report, claim))
        )  # fmt: skip
        self._picture.add_done_callback(self._landed)

    def _clear_picture(self) -> None:
        self.image.image = BLANK
        self.image.visible = False
        self.caption.content = ""

    def _landed(self, future: Future[Any]) -> None:
        if not future.cancelled():
            with self.status.lock:
                self._put()

    def _put(self) -> None:
        """Put what the background thread finished on the page (under the dashboard's lock)."""
        if self._closed:
            return
        if self._read is not None and self._read.done():
            read, self._read = self._read, None
            try:
                shelf, reports, answers = read.result()
            except Exception as error:  # the page goes on without the reports
                self.reports.content = f"⚠ could not read the committed reports: {error}"
            else:
                self.shelf = shelf
                self.reports.content = reports
                self.answers.content = answers
                set_options(self.report, [r.name for r in shelf.reports], cv.NO_REPORTS)
                self.show_report()
        if self._picture is not None and self._picture.done():
            picture, self._picture = self._picture, None
            try:
                name, claim, image, caption = picture.result()
            except Exception as error:
                self.caption.content = f"⚠ could not draw the claim's runs: {error}"
            else:
                if (name, claim) == (self.report.value, self.claim.value):
                    self.image.image = image
                    self.image.visible = True
                    self.caption.content = caption

    def close(self) -> None:
        self._closed = True
        self._pool.shutdown(wait=False, cancel_futures=True)
        if self.pages is not None:
            self.pages.close()


def populate_committed(gui: viser.GuiApi, status: Status) -> CommittedSection:
    """Add the committed reports' controls (inside the current container) and read them."""
    with gui.add_folder("The thesis's answers"):
        gui.add_markdown(
            "<small>Per question of the thesis, its answering claim's verdict in the committed "
            "reports of this checkout (docs/experiments), as docs/experiments/README.md has "
            "it. Hover a question for its claim and Δ.</small>"
        )
        answers = gui.add_markdown("Reading the committed reports…")
    with gui.add_folder("Committed reports"):
        section = CommittedSection(
            status=status,
            answers=answers,
            reports=gui.add_markdown(""),
            report=gui.add_dropdown("Report", (cv.NO_REPORTS,)),
            header=gui.add_markdown(""),
            claims=gui.add_markdown(""),
            claim=gui.add_dropdown("Claim", (cv.NO_CLAIMS,)),
            image=gui.add_image(BLANK, format="png", visible=False),
            caption=gui.add_markdown(""),
        )

    section.report.on_update(status.guard(section.show_report))
    section.claim.on_update(status.guard(section.show_claim))
    section.read()
    return section
