"""Who may talk to what this lab starts: Dask over TLS, scheduler addresses, dashboard exposure.

Dask's protocol deserialises pickles: whoever can connect to a scheduler or worker runs code as
its user. So the local cluster of `experiment run` speaks TLS with a key pair made for it in
memory (`Security.temporary()`, mutual authentication: only this process holds the client key),
and an external scheduler is best reached at a `tls://` address with certificates configured as
Dask reads them (see docs/security.md).
"""

from __future__ import annotations

import ipaddress
import socket
from typing import Any

LOOPBACK_NAMES = ("localhost", "localhost.localdomain", "ip6-localhost")


class AddressError(ValueError):
    """A scheduler address that is not a Dask address."""


def local_cluster_security() -> Any:
    """A `distributed.Security` for a local cluster: TLS with a throw-away self-signed key pair
    that every role (scheduler, workers, this client) shares, held in memory only."""
    from distributed.security import Security

    return Security.temporary()


def check_scheduler_address(address: str) -> str:
    """A Dask scheduler address checked for form (`tls://HOST:PORT`, `tcp://HOST:PORT`, or
    `HOST:PORT`, which Dask reads as tcp); returns it unchanged.

    Raises:
        AddressError: naming what is wrong with it.
    """
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address, strict=False)
        if scheme not in ("tcp", "tls"):
            raise ValueError(f"the protocol must be tls:// or tcp://, not {scheme}://")
        host, port = parse_host_port(location)
        if not host:
            raise ValueError("no host")
        if not 1 <= int(port) <= 65535:
            raise ValueError(f"port {port} is not in 1..65535")
    except (ValueError, TypeError) as error:
        raise AddressError(
            f"--scheduler {address!r} is not a Dask scheduler address "
            f"(tls://HOST:PORT or tcp://HOST:PORT): {error}"
        ) from None
    return address


def plain_tcp_warning(address: str) -> str | None:
    """A warning for a scheduler reached over plain tcp (None for tls://)."""
    if address.startswith("tls://"):
        return None
    return (
        f"warning: {address} is plain tcp: anyone who can reach the scheduler or its workers can "
        "run code as them; use tls:// with certificates (see docs/security.md)"
    )


def is_loopback(host: str) -> bool:
    """Whether `host` names only this machine (127.0.0.0/8, ::1, localhost)."""
    if host.lower() in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError):
        return False
    return bool(infos) and all(ipaddress.ip_address(i[4][0]).is_loopback for i in infos)
