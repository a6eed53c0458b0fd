"""`gnp-lab serve`: the dashboard, on 127.0.0.1 unless told otherwise (and warned)."""

from __future__ import annotations

import argparse
import socket
import sys
from typing import TYPE_CHECKING

from app.cli.parser import PROG, UsageError
from app.store import resolve_run
from app.system.security import is_loopback

if TYPE_CHECKING:
    pass


# --- serve ----------------------------------------------------------------------------------


def _check_host(host: str) -> None:
    """Refuse an address this machine cannot listen on, before viser's server thread tries."""
    try:
        infos = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as error:
        raise UsageError(f"--host {host!r} is not an address of this machine ({error})") from None
    family, kind, _, _, address = infos[0]
    try:
        with socket.socket(family, kind) as probe:
            probe.bind(address)
    except OSError as error:
        raise UsageError(f"cannot listen on --host {host!r}: {error.strerror}") from None


def cmd_serve(args: argparse.Namespace) -> int:
    if args.run is not None:
        resolve_run(args.runs_dir, args.run)
    _check_host(args.host)
    if not is_loopback(args.host):
        if not args.allow_remote:
            raise UsageError(
                f"--host {args.host} lets other machines reach the dashboard, which has no "
                "login and runs training, exports and experiments as you; keep 127.0.0.1 and "
                f"use an SSH tunnel (ssh -L {args.port}:127.0.0.1:{args.port} HOST), or add "
                "--allow-remote"
            )
        sys.stderr.write(
            f"{PROG}: WARNING: the dashboard on {args.host} has no login: anyone who can "
            "reach this port can train, export and start experiments as you\n"
        )
    from app.dashboard import serve

    serve(host=args.host, port=args.port, runs_dir=args.runs_dir, run=args.run)
    return 0
