"""May a fleet start here? Its run directory held, its router able to listen, the router's rate limits.

Before anything is started the launcher holds the run directory (:class:`RunDirLock`: one
launcher at a time writes logs, credentials and metrics there), checks that the router can
listen on every endpoint asked (:func:`check_listen`: a busy port is a usage error, not a
traceback from Zenoh) and writes the router's rate limits (:func:`rate_limits`).
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
import stat
from pathlib import Path
from typing import Any

from cdus.wire import keys


# Router-side rate limits (Zenoh's own ``downsampling``, realtime runs only: it is wall-clock
# based, and a lockstep run goes many times faster than real time and must lose nothing).
# Zenoh keeps one timer per rule and per incoming link (flow ingress): a flooder's link gets
# its own budget, so a flood on vehicle v's ω key reaches v's listeners at most
# OMEGA_MARGIN x the broadcast rate, and v's own messages, on v's own link, are not starved.
# The margin absorbs jitter: Zenoh drops a message that follows the previous one of its
# link by less than 1 / rate (no burst allowance), so a genuine ω is dropped only if it
# arrives less than a quarter period after the one before.
OMEGA_MARGIN = 4.0
LINKS = ("direct", "router")  # how ω travels between neighbours (docs/architecture.md)
COMMAND_HZ = 10.0  # the world's command inbox (ground stations): one command per `cdus gs` call


def rate_limits(fleet: str, ids: tuple[str, ...] | list[str], broadcast_hz: float) -> list[dict]:
    """The router's ``downsampling`` section: every vehicle's ω (any listener set) at
    OMEGA_MARGIN x ``broadcast_hz``, the world's command inbox at COMMAND_HZ, per incoming
    link. Not the world's ctl or the launcher's key: the world sends genuine bursts there
    (several faults in one tick); under --secure only the world may publish them."""
    omega = [{"key_expr": f"{keys.prefix(fleet)}/to/*/omega/{vid}", "freq": OMEGA_MARGIN * broadcast_hz}
             for vid in ids]
    # any recipient set: the world also hears to/+world+x+/cmd/..., which a flooder could pick
    commands = [{"key_expr": f"{keys.prefix(fleet)}/to/*/cmd/*", "freq": COMMAND_HZ}]
    return [{"id": "cdus-rate-limits", "flows": ["ingress"], "messages": ["put"], "rules": omega + commands}]


class RunDirInUse(Exception):
    """Another launcher runs into this run directory now: nothing was started."""


class RunDirError(Exception):
    """The run directory cannot be written (a full disk, a read-only directory): nothing was started."""


LOCK_NAME = ".launch.lock"  # in the run directory: flock'ed by the launcher running into it


class RunDirLock:
    """An exclusive hold on a run directory while a fleet runs into it (logs, credentials,
    metrics): ``flock`` on ``<run>/.launch.lock``, as ``cdus sweep`` holds its ``--out``. The
    kernel lets go when the holder dies (even by SIGKILL), so the directory of a dead launcher
    is free again; the file stays (removing it would race a launcher taking it)."""

    def __init__(self, run: Path):
        self.path = run / LOCK_NAME
        try:  # a read-only or full directory, a lock that is a symlink (never followed) or not a file: RunDirError
            run.mkdir(parents=True, exist_ok=True)
            # close-on-exec: the children never hold it (they die with the launcher anyway); non-blocking: a FIFO
            self.fd: int | None = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW
                                          | os.O_NONBLOCK, 0o644)
        except OSError as e:
            not_file = e.errno in (errno.ELOOP, errno.EISDIR)
            why = "a symbolic link (never followed)" if e.errno == errno.ELOOP else e.strerror or str(e)
            raise RunDirError(f"cannot hold the run directory {run} ({e.filename}: {why}); nothing was started; "
                              + (f"remove {self.path} or give another --logs" if not_file else
                                 "make it writable or give another --logs")) from None
        if not stat.S_ISREG(os.fstat(self.fd).st_mode):
            os.close(self.fd)
            self.fd = None
            raise RunDirError(f"cannot hold the run directory {run}: {self.path} is not a regular file; nothing "
                              f"was started; remove it or give another --logs")
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            self.fd = None
            raise RunDirInUse(f"another `cdus launch` is running into {run} now (it holds {self.path}); wait for "
                              f"it to end or give another --logs") from None

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> "RunDirLock":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()


class ListenError(Exception):
    """The router could not listen where it was asked (a busy port, an address not of this
    host): a usage error; nothing was started."""


_STREAM_PROTOCOLS = ("tcp", "tls", "ws")  # over TCP
_DATAGRAM_PROTOCOLS = ("udp", "quic")  # over UDP


def listen_problem(ep: str) -> str | None:
    """Why the router cannot listen on ``ep`` (an IP endpoint whose address is taken or not of
    this host), or None (free, port 0, or not an IP endpoint: Zenoh says). Binds the address as
    Zenoh will (SO_REUSEADDR: a port in TIME_WAIT is free) and lets it go at once."""
    proto = ep.partition("/")[0]
    if proto not in _STREAM_PROTOCOLS + _DATAGRAM_PROTOCOLS:
        return None
    rest = ep.partition("/")[2].split("#", 1)[0].split("?", 1)[0]
    host, _, port = rest.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not port.isdigit() or int(port) == 0:
        return None
    kind = socket.SOCK_STREAM if proto in _STREAM_PROTOCOLS else socket.SOCK_DGRAM
    try:
        infos = socket.getaddrinfo(host, int(port), type=kind)
    except socket.gaierror as e:
        return f"{host!r} is not an address of this host ({e.strerror})"
    for family, socktype, protocol, _, address in infos:
        with socket.socket(family, socktype, protocol) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind(address)
            except OSError as e:
                return f"{e.strerror or e} (another process is listening there?)" \
                    if e.errno == errno.EADDRINUSE else str(e.strerror or e)
    return None


def check_listen(endpoints: tuple[str, ...] | list[str]) -> None:
    """Raise ListenError naming the first endpoint the router cannot listen on."""
    for ep in endpoints:
        why = listen_problem(ep)
        if why is not None:
            raise ListenError(f"the router cannot listen on {ep}: {why}; choose another endpoint "
                              f"(or leave out --listen for a free port on 127.0.0.1)")
