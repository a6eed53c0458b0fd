"""The dashboard in a child process, for a headless browser: the browser tests and bench/soak.py.

Only the standard library here; Playwright is imported by the callers that drive the browser.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Sequence
from pathlib import Path


def chromium_executable() -> str:
    """The Chromium the lab's browser tests and benches drive: `$GNP_LAB_CHROMIUM`, else
    Debian's."""
    return os.environ.get("GNP_LAB_CHROMIUM", "/usr/bin/chromium")


CHROMIUM_ARGS = (
    "--headless",
    "--no-sandbox",  # CI runs as root
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    # The machine has no network: without these Chromium keeps dialling out and failing.
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)
"""Flags for Debian's headless Chromium (Playwright's own browser download is never used)."""


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def start_dashboard(
    runs_dir: Path, log_path: Path, extra: Sequence[str] = (), timeout: float = 90.0
) -> tuple[subprocess.Popen[bytes], str]:
    """Run `gnp-lab serve` on a free local port; return the process and its URL once it answers.

    Args:
        runs_dir: the runs directory to serve.
        log_path: file that receives the server's output (quoted if it does not start).
        extra: more `gnp-lab serve` arguments, e.g. ("--run", "cs").
        timeout: seconds to wait for the page.

    Raises:
        RuntimeError: the server exited or did not answer in time (its output included).
    """
    port = free_port()
    command = [
        sys.executable,
        "-c",
        "import sys; from app.cli import main; sys.exit(main())",
        "serve",
        "--port",
        str(port),
        "--runs-dir",
        str(runs_dir),
        *extra,
    ]
    with log_path.open("wb") as log:  # the child keeps its own copy of the descriptor
        process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + timeout
    while True:
        try:
            urllib.request.urlopen(url, timeout=2).close()
            return process, url
        except OSError:
            if process.poll() is not None or time.monotonic() > deadline:
                process.kill()
                process.wait()
                output = log_path.read_text(errors="replace")
                raise RuntimeError(f"dashboard did not start: {output}") from None
            time.sleep(0.3)


def stop_dashboard(process: subprocess.Popen[bytes]) -> None:
    """Stop a dashboard started by `start_dashboard` (SIGTERM, then SIGKILL after 20 s)."""
    process.terminate()
    try:
        process.wait(20)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
