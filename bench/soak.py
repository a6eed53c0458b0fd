"""Soak test of the dashboard: live replay with N headless browser tabs, server RSS over time.

Runs `gnp-lab serve` in a subprocess, opens N tabs in Debian's headless Chromium (Playwright),
and samples the server's resident memory and the live robot's step count. A session must not
grow memory without bound: the tail of the run should be flat.

    .venv/bin/python bench/soak.py --minutes 10 --tabs 3
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

from app.dashboard.headless import (
    CHROMIUM_ARGS,
    chromium_executable,
    start_dashboard,
    stop_dashboard,
)

REPO = Path(__file__).resolve().parents[1]


def rss_mib(pid: int) -> float:
    """Resident set size of a process, MiB (from /proc)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError(f"no VmRSS for pid {pid}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="how long to run")
    parser.add_argument("--tabs", type=int, default=3, help="browser tabs kept open")
    parser.add_argument("--every", type=float, default=30.0, help="seconds between samples")
    parser.add_argument("--runs-dir", default=str(REPO / "saved_runs"), help="runs to serve")
    parser.add_argument("--chromium", default=chromium_executable(), help="browser executable")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory() as folder:
        return soak(args, Path(folder) / "server.log")


def soak(args: argparse.Namespace, log_path: Path) -> int:
    """Serve, open the tabs, sample RSS until the time is up; 0 when the server survived."""
    from playwright.sync_api import sync_playwright

    try:
        server, url = start_dashboard(Path(args.runs_dir), log_path, timeout=120)
    except RuntimeError as error:
        print(error, file=sys.stderr)
        return 1
    try:
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=args.chromium, args=CHROMIUM_ARGS)
            pages = []
            for _ in range(args.tabs):
                page = browser.new_page(viewport={"width": 1280, "height": 720})
                page.goto(url)
                page.get_by_text("Status:").first.wait_for(timeout=120_000)
                pages.append(page)
            print(f"server pid {server.pid}, {args.tabs} tabs on {url}")
            print(f"{'minute':>7} {'server RSS MiB':>15} {'robot step':>11}")
            start = time.monotonic()
            samples: list[tuple[float, float]] = []
            while True:
                elapsed = time.monotonic() - start
                readout = pages[-1].get_by_text(re.compile("^on show:")).first.inner_text()
                step = re.search(r"step (\d+)", readout)
                rss = rss_mib(server.pid)
                samples.append((elapsed, rss))
                print(f"{elapsed / 60:7.1f} {rss:15.1f} {step.group(1) if step else '?':>11}")
                sys.stdout.flush()
                if elapsed >= args.minutes * 60:
                    break
                pages[-1].wait_for_timeout(args.every * 1000)
            browser.close()
        if server.poll() is not None:
            print("the server died during the soak", file=sys.stderr)
            return 1
        # Growth over the second half (after caches and buffers have filled).
        half = [rss for t, rss in samples if t >= samples[-1][0] / 2]
        print(
            f"RSS first {samples[0][1]:.1f} MiB, max {max(r for _, r in samples):.1f} MiB, "
            f"last {samples[-1][1]:.1f} MiB; growth over the second half "
            f"{half[-1] - half[0]:+.1f} MiB"
        )
        return 0
    finally:
        stop_dashboard(server)


if __name__ == "__main__":
    sys.exit(main())
