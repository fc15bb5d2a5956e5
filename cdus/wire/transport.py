"""How a process reaches the others: Zenoh configuration and the flags every process shares.

Every cdus process takes the same transport flags, named as in zenoh-python's examples:

    --mode {peer,client,router}   --connect ENDPOINT ...   --listen ENDPOINT ...
    --zenoh-config FILE           (a zenoh json5 config; flags given override it)

Default topology (docs/architecture.md, "Processes"): one process opens a session in router
mode listening on ``tcp/127.0.0.1:<port>`` (or a unix socket), the launcher in ``cdus
launch`` (a world started by hand otherwise); everything else connects to it as a client.
Multicast scouting is switched off in every config this module builds, including one read
from a user's file: it would send packets off this machine. Connect to explicit endpoints.
"""

from __future__ import annotations

import argparse
import ipaddress
import json
import os
import socket
from dataclasses import dataclass, field
from typing import Sequence

import zenoh

MODES = ("peer", "client", "router")
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"  # where a process started by hand looks for (or opens) the router
DEFAULT_LEASE_MS = 1000  # the launcher's liveliness lease: a hung process is gone after 1 s (zenoh's: 10 s)
CONNECT_TIMEOUT_S = 30.0


@dataclass(frozen=True)
class Transport:
    mode: str = "client"
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    config_file: str | None = None
    lease_ms: int | None = None  # liveliness lease; None keeps Zenoh's default (10 s)
    extra: tuple[tuple[str, str], ...] = field(default=())  # (json5 key, json5 value) pairs

    def args(self) -> list[str]:
        """The command-line flags that reproduce this transport in a child process."""
        out = ["--mode", self.mode]
        for ep in self.connect:
            out += ["--connect", ep]
        for ep in self.listen:
            out += ["--listen", ep]
        if self.config_file:
            out += ["--zenoh-config", self.config_file]
        if self.lease_ms:
            out += ["--lease-ms", str(self.lease_ms)]
        return out


ENDPOINT_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream", "unixpipe", "vsock")
_IP_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws")


def endpoint(text: str) -> str:
    """An endpoint as argparse takes it: ``<protocol>/<address>``, ``host:port`` for IP
    protocols (a port 0-65535). Anything else is a usage error naming the form."""
    proto, sep, address = text.partition("/")
    if not sep or proto not in ENDPOINT_PROTOCOLS or not address:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not an endpoint: expected <protocol>/<address> with a protocol of "
            f"{', '.join(ENDPOINT_PROTOCOLS)}, e.g. tcp/127.0.0.1:7447 or unixsock-stream//tmp/cdus.sock")
    if proto in _IP_PROTOCOLS:
        host, colon, port = address.split("#")[0].rpartition(":")
        if not colon or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
            raise argparse.ArgumentTypeError(f"{text!r}: expected {proto}/<host>:<port> with a port 0-65535, "
                                             f"e.g. {proto}/127.0.0.1:7447")
    return text


LOCAL_PROTOCOLS = ("unixsock-stream", "unixpipe")  # reachable from this host only


def endpoint_host(ep: str) -> str:
    """``tls/10.0.0.1:7447#opts`` -> ``10.0.0.1``; ``tcp/[::1]:7447`` -> ``::1``."""
    rest = ep.partition("/")[2].split("#", 1)[0].split("?", 1)[0]
    host = rest.rsplit(":", 1)[0]
    return host[1:-1] if host.startswith("[") and host.endswith("]") else host


def is_local_endpoint(ep: str) -> bool:
    """Whether only this host can reach ``ep``: a unix socket or pipe, or an IP protocol on a
    loopback address literal (127.0.0.0/8, ::1). A host name (even ``localhost``), a wildcard
    (0.0.0.0, ::) or any other address is not: it is, or may be, reachable from elsewhere."""
    proto = ep.partition("/")[0]
    if proto in LOCAL_PROTOCOLS:
        return True
    if proto not in _IP_PROTOCOLS:
        return False
    try:
        return ipaddress.ip_address(endpoint_host(ep)).is_loopback
    except ValueError:
        return False


def router_listen(t: Transport) -> tuple[str, ...]:
    """The endpoints a router made from ``t`` listens on: its own, else its config file's, else
    Zenoh's default for a router (every interface, ``tcp/[::]:7447``)."""
    if t.listen:
        return t.listen
    conf = zenoh.Config.from_file(t.config_file) if t.config_file else zenoh.Config()
    eps = json.loads(conf.get_json("listen/endpoints"))
    if isinstance(eps, dict):
        eps = eps.get("router", [])
    return tuple(str(e) for e in eps)


def exposed_endpoints(t: Transport) -> tuple[str, ...]:
    """The endpoints of router ``t`` that another host may reach (see :func:`is_local_endpoint`)."""
    return tuple(ep for ep in router_listen(t) if not is_local_endpoint(ep))


def add_transport_args(p: argparse.ArgumentParser, default_mode: str = "client") -> None:
    g = p.add_argument_group("zenoh transport (same flags on every cdus process)")
    g.add_argument("--mode", choices=MODES, default=None,
                   help=f"zenoh session mode (default: {default_mode})")
    g.add_argument("-e", "--connect", action="append", default=[], metavar="ENDPOINT", type=endpoint,
                   help="endpoint to connect to, e.g. tcp/127.0.0.1:7447 or unixsock-stream//tmp/cdus.sock")
    g.add_argument("-l", "--listen", action="append", default=[], metavar="ENDPOINT", type=endpoint,
                   help="endpoint to listen on, e.g. tcp/127.0.0.1:7447")
    g.add_argument("--zenoh-config", metavar="FILE",
                   help="a zenoh json5 config file; --mode/--connect/--listen override it "
                        "(multicast scouting is forced off)")
    g.add_argument("--lease-ms", type=int, default=None, metavar="MS",
                   help="liveliness lease: how soon a hung process is declared gone (zenoh default 10000)")
    p.set_defaults(_default_mode=default_mode)


def transport_from_args(args: argparse.Namespace) -> Transport:
    return Transport(
        mode=args.mode or getattr(args, "_default_mode", "client"),
        connect=tuple(args.connect or ()),
        listen=tuple(args.listen or ()),
        config_file=args.zenoh_config,
        lease_ms=args.lease_ms,
    )


def zenoh_config(t: Transport):
    """A ``zenoh.Config`` for ``t``, multicast scouting off whatever the file says."""
    conf = zenoh.Config.from_file(t.config_file) if t.config_file else zenoh.Config()
    conf.insert_json5("mode", json.dumps(t.mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if t.connect or not t.config_file:
        conf.insert_json5("connect/endpoints", json.dumps(list(t.connect)))
    if t.listen or not t.config_file:
        # a peer or router with no listen endpoint given would listen on every interface
        conf.insert_json5("listen/endpoints", json.dumps(list(t.listen)))
    if t.mode != "router" and not t.config_file:
        conf.insert_json5("scouting/gossip/enabled", "false")
    if t.mode != "client" and not t.config_file:
        # what a router or peer waits in zenoh.open for scouting answers (Zenoh's default 500 ms):
        # with multicast off there are none to wait for (a router's gossip is news of routers that
        # connect later, and reaches it whenever they do). Measured: the fleet's router opened in
        # 0.50 s -> 0.001 s, every `cdus launch` half a second sooner (tests/wire/test_transport.py)
        conf.insert_json5("scouting/delay", "0")
    if t.connect:
        # wait for the router instead of failing at once, so start order does not matter
        conf.insert_json5("connect/timeout_ms", str(int(CONNECT_TIMEOUT_S * 1000)))
        conf.insert_json5("connect/retry", "{period_init_ms: 100, period_max_ms: 500, period_increase_factor: 2}")
    if t.lease_ms:
        conf.insert_json5("transport/link/tx/lease", str(int(t.lease_ms)))
    for key, value in t.extra:
        if key in OPTIONAL_KEYS:  # a Zenoh older than this setting (eclipse-zenoh>=1.0 is allowed): without it
            try:
                conf.insert_json5(key, value)
            except zenoh.ZError:
                pass
            continue
        conf.insert_json5(key, value)
    return conf


def open_session(t: Transport):
    return zenoh.open(zenoh_config(t))


# Zenoh's runtime (its thread pools) is configured per process, by the ZENOH_RUNTIME environment
# variable, read once when the process first needs the runtime. Zenoh's default suits a process
# that has cores to itself: here dozens share two, and every idle pool thread is a wake-up.
#: every process the launcher starts (world, agents): one worker thread, the network tasks
#: (accept, receive, transmit) handed over to it (measured: lockstep lake_circle 13x -> 17x
#: real time on 2 cores; 6 threads per agent, 3 of them Zenoh's)
CHILD_RUNTIME = "(app: (worker_threads: 1), acc: (handover: app), rx: (handover: app), tx: (handover: app))"
#: the launcher's own session, the fleet's router, keeps Zenoh's default pools ("default": the
#: launcher sets nothing; rx-0, rx-1, tx-0, acc-0, app-0, net-0). Fewer routing threads cost
#: less CPU (SMALL_ROUTER_RUNTIME: router 17 -> 10 % of a core on the 64-vehicle realtime ring)
#: but are not safe: the router forwards a message sent with congestion control BLOCK by
#: waiting for room in the outgoing link's queue (up to wait_before_close, 1 s), on the thread
#: that routes. On one routing thread that stalls every link: a partitioned vehicle's link
#: stalled the others' (a boat lost and back, a UAV noticed 10 s late:
#: tests/e2e/test_multihost.py, partition), and with transmit on that thread too a flooded
#: lockstep fleet hung (tests/e2e/test_hostile.py). bench/realtime_capacity.py
#: --router-runtime default,small,single compares them.
ROUTER_RUNTIME = "default"
SMALL_ROUTER_RUNTIME = "(app: (worker_threads: 1), acc: (handover: app), rx: (handover: app), tx: (worker_threads: 1))"
RUNTIME_ENV = "ZENOH_RUNTIME"
#: names the launcher's own runtime ("default": Zenoh's; a bench compares them); ZENOH_RUNTIME, if set, wins
ROUTER_RUNTIME_ENV = "CDUS_ROUTER_RUNTIME"


def use_runtime(spec: str, env=None) -> str:
    """Give this process (``env``: os.environ) Zenoh runtime ``spec`` unless the user set
    ZENOH_RUNTIME; returns the one in force. Only effective before the process's first Zenoh
    session (Zenoh reads the variable once)."""
    global _OWN_RUNTIME
    if env is None:
        env = os.environ
        if RUNTIME_ENV not in env:
            _OWN_RUNTIME = spec
    return env.setdefault(RUNTIME_ENV, spec)


_OWN_RUNTIME: str | None = None  # what use_runtime gave this process (not the user's choice)


def children_runtime(env=None) -> str:
    """The ZENOH_RUNTIME for the processes this one starts: the user's, else CHILD_RUNTIME (not
    the router's that :func:`use_runtime` may have given this process: a program that launches
    one fleet after another would pass it on)."""
    env = os.environ if env is None else env
    mine = env.get(RUNTIME_ENV)
    return CHILD_RUNTIME if mine is None or mine == _OWN_RUNTIME else mine


def with_default_endpoint(t: Transport) -> Transport:
    """``t``, connecting to (client, peer) or listening on (router) DEFAULT_ENDPOINT if it names no
    endpoint and no config file."""
    if t.connect or t.listen or t.config_file:
        return t
    if t.mode == "router":
        return Transport(mode="router", listen=(DEFAULT_ENDPOINT,), lease_ms=t.lease_ms, extra=t.extra)
    return Transport(mode=t.mode, connect=(DEFAULT_ENDPOINT,), lease_ms=t.lease_ms, extra=t.extra)


def free_tcp_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago (for a fresh router endpoint)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# cdus carries its own send time in every payload; the router's per-message timestamps
# would add 26 bytes to each delivered ω message (measured: 68 -> 42 bytes on the wire).
NO_TIMESTAMPS = (("timestamping/enabled", "{router: false, peer: false, client: false}"),)
# A router holds a message for a link whose queue is full (ω, state and the world's ctl
# are sent with congestion control BLOCK) at most this long before it closes that link.
# Zenoh's default, 5 s, stalls every vehicle whose ω is also addressed to a vehicle cut
# off by a partition, link after link (measured: 11 s for two cut-off UAVs); one lease
# is how long a silent vehicle is given anyway (docs/multihost.md, "Partitions").
BLOCK_BEFORE_CLOSE = (("transport/link/tx/queue/congestion_control/block/wait_before_close",
                       str(DEFAULT_LEASE_MS * 1000)),)  # µs
#: Commands to the world and their answers (world/cmd/**, queries and replies: BLOCK by Zenoh's
#: default) are dropped by the router when the link they go to is full, not waited for: a ground
#: station's flood of command queries (3000 in 0.05 s) held the router's routing thread on the
#: world's full link for wait_before_close, then the router closed that link: a lockstep world
#: lost every vehicle and got them back, then usv1 was lost for 120-220 s of simulated time (a
#: changed result), and every ground station watching saw the world leave. A command dropped so
#: is not answered (`cdus gs` says so: no answer, exit 3).
COMMANDS_DROP = (("qos/network", json.dumps([{
    "id": "commands-drop", "messages": ["query"], "flows": ["ingress"],
    "key_exprs": ["cdus/*/world/cmd/**"], "overwrite": {"congestion_control": "drop"}}])),)
ROUTER_EXTRA = NO_TIMESTAMPS + BLOCK_BEFORE_CLOSE + COMMANDS_DROP
#: settings a Zenoh that does not know them goes without (qos/network: Zenoh 1.10 has it)
OPTIONAL_KEYS = frozenset({"qos/network"})


def router(listen: Sequence[str] = (), config_file: str | None = None) -> Transport:
    """The fleet's router (the launcher's session): ``listen`` (default: a fresh port on
    loopback), ROUTER_EXTRA's settings over ``config_file``'s."""
    eps = tuple(listen) or (() if config_file else (f"tcp/127.0.0.1:{free_tcp_port()}",))
    return Transport(mode="router", listen=eps, config_file=config_file, extra=ROUTER_EXTRA)


def local_router(port: int | None = None) -> Transport:
    """The default world transport: a router on loopback (ROUTER_EXTRA's settings)."""
    return Transport(mode="router", listen=(f"tcp/127.0.0.1:{port or free_tcp_port()}",), extra=ROUTER_EXTRA)


def client_of(router: Transport, base: Transport | None = None) -> Transport:
    """A client connecting to ``router``'s listen endpoints (keeping ``base``'s config file): its
    own, else its config file's (:func:`router_listen`; a router given only ``--zenoh-config
    FILE`` listens where the file says, and its clients went to DEFAULT_ENDPOINT: a launch's
    world and vehicles never reached it), an any-address one (``0.0.0.0``, ``[::]``) on loopback."""
    eps = tuple(ep.replace("/0.0.0.0:", "/127.0.0.1:").replace("/[::]:", "/127.0.0.1:") for ep in router_listen(router))
    return Transport(mode="client", connect=eps, config_file=base.config_file if base else None,
                     lease_ms=router.lease_ms)
