"""A shop network in Linux network namespaces: several "hosts" on one switch, on this machine.

The tests and the bench stand in for a shop floor of computers (a discovery-server host,
machine controllers, a cell controller) with one network namespace per host, joined by veth
cables to a bridge that lives in a namespace of its own (the switch). Nothing is added to
the root namespace, so no packet of ours can reach a real interface, and every address is
in 198.18.0.0/24 (RFC 2544's benchmarking range). IPv6 is switched off in every namespace
so that the kernel sends no router solicitations or multicast listener reports of its own.

The plan (names, addresses, the ``ip`` commands that build and remove it) is plain data made
here; ``ShopFloor`` is the thin shell that runs those commands, starts processes on the
hosts and always takes everything down again. Needs root (CAP_NET_ADMIN) and iproute2.
"""
from __future__ import annotations

import ipaddress
import json
import os
import signal
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

SUBNET = ipaddress.ip_network("198.18.0.0/24")
PREFIX_LEN = SUBNET.prefixlen
NETNS_DIR = Path("/run/netns")


@dataclass(frozen=True)
class Host:
    """One computer of the shop floor: its role, namespace, address and network link."""

    role: str  # "server", "m1", "cell", ...
    netns: str  # the namespace's name (unique per run)
    address: str  # its address on the shop network
    link: str  # its interface inside netns (the host's end of the cable)
    port: str  # the cable's other end, a port of the switch


@dataclass(frozen=True)
class ShopNetwork:
    """The plan of a shop network: a switch namespace and the hosts plugged into it."""

    tag: str  # unique per run: every name below starts with it
    switch: str  # the switch's namespace
    bridge: str  # the bridge device inside it
    hosts: dict[str, Host] = field(default_factory=dict)

    def __getitem__(self, role: str) -> Host:
        return self.hosts[role]


def run_tag(pid: int | None = None, serial: int = 0) -> str:
    """A short tag unique to this process and call (namespaces are host-wide, and parallel
    test runs must not collide); interface names derived from it stay within 15 bytes."""
    pid = os.getpid() if pid is None else pid
    return f"cs{pid % 100000:05d}{serial % 100:02d}"


def plan_network(roles: list[str], tag: str) -> ShopNetwork:
    """Hosts for ``roles`` in order at 198.18.0.1, .2, ...; names are ``<tag>-<role>``."""
    if len(set(roles)) != len(roles):
        raise ValueError(f"roles must be unique: {roles}")
    if len(roles) > SUBNET.num_addresses - 2:
        raise ValueError(f"at most {SUBNET.num_addresses - 2} hosts on {SUBNET}")
    hosts = {}
    for i, role in enumerate(roles, start=1):
        hosts[role] = Host(role=role, netns=f"{tag}-{role}", address=str(SUBNET.network_address + i),
                           link=f"{tag}h{i}", port=f"{tag}p{i}")
    return ShopNetwork(tag=tag, switch=f"{tag}-switch", bridge=f"{tag}br", hosts=hosts)


def _no_ipv6(netns: str) -> list[list[str]]:
    return [["ip", "netns", "exec", netns, "sysctl", "-q", "-w", f"net.ipv6.conf.{which}.disable_ipv6=1"]
            for which in ("all", "default")]


def setup_commands(net: ShopNetwork) -> list[list[str]]:
    """The ``ip`` commands that build the network, in order. Each cable is made with both
    ends directly inside their namespaces, so nothing ever appears in the root namespace."""
    sw = net.switch
    commands = [["ip", "netns", "add", sw], *_no_ipv6(sw),
                ["ip", "-n", sw, "link", "add", net.bridge, "type", "bridge"],
                ["ip", "-n", sw, "link", "set", net.bridge, "up"],
                ["ip", "-n", sw, "link", "set", "lo", "up"]]
    for host in net.hosts.values():
        commands += [["ip", "netns", "add", host.netns], *_no_ipv6(host.netns),
                     ["ip", "-n", host.netns, "link", "set", "lo", "up"],
                     ["ip", "-n", sw, "link", "add", host.port, "type", "veth", "peer", "name", host.link,
                      "netns", host.netns],
                     ["ip", "-n", sw, "link", "set", host.port, "master", net.bridge],
                     ["ip", "-n", sw, "link", "set", host.port, "up"],
                     ["ip", "-n", host.netns, "addr", "add", f"{host.address}/{PREFIX_LEN}", "dev", host.link],
                     ["ip", "-n", host.netns, "link", "set", host.link, "up"]]
    return commands


def teardown_commands(net: ShopNetwork) -> list[list[str]]:
    """Deleting the namespaces removes their devices (and the veth cables with them)."""
    return [["ip", "netns", "delete", ns] for ns in [*(h.netns for h in net.hosts.values()), net.switch]]


def in_host(host: Host, argv: list[str]) -> list[str]:
    """``argv`` run on ``host`` (in its network namespace)."""
    return ["ip", "netns", "exec", host.netns, *argv]


def link_command(host: Host, up: bool) -> list[str]:
    """Plug the host's cable in or pull it (the host keeps its address and loopback)."""
    return ["ip", "-n", host.netns, "link", "set", host.link, "up" if up else "down"]


ETH_IPV4, ETH_ARP = 0x0800, 0x0806


def classify_frame(frame: bytes) -> tuple[str, str]:
    """What a frame seen on the switch is: ("shop", source address) for IPv4 between shop
    addresses, ("arp", sender) for ARP about shop addresses, ("foreign", what) for anything
    else (IPv6, multicast, another address): the traffic that must never appear."""
    if len(frame) < 14:
        return "foreign", "runt frame"
    kind = int.from_bytes(frame[12:14], "big")
    if kind == ETH_IPV4 and len(frame) >= 34:
        src, dst = ipaddress.ip_address(frame[26:30]), ipaddress.ip_address(frame[30:34])
        if src in SUBNET and dst in SUBNET:
            return "shop", str(src)
        return "foreign", f"IPv4 {src} -> {dst} (protocol {frame[23]})"
    if kind == ETH_ARP and len(frame) >= 42:
        sender, target = ipaddress.ip_address(frame[28:32]), ipaddress.ip_address(frame[38:42])
        if sender in SUBNET and target in SUBNET:
            return "arp", str(sender)
        return "foreign", f"ARP {sender} -> {target}"
    return "foreign", f"ethertype 0x{kind:04x}"


def link_stats(ip_json: list[dict]) -> dict[str, int]:
    """Packets and bytes a link sent and received, from ``ip -s -j link show dev X``."""
    stats = ip_json[0]["stats64"]
    return {f"{way}_{what}": stats[way][what] for way in ("rx", "tx") for what in ("packets", "bytes")}


def existing_namespaces(prefix: str) -> list[str]:
    """Namespaces whose names start with ``prefix`` (what a teardown must have removed)."""
    return sorted(p.name for p in NETNS_DIR.glob(f"{prefix}*")) if NETNS_DIR.is_dir() else []


class Talker:
    """A process whose stdout is JSON lines (a test's cell controller, the sniffer), read
    by a thread as they come, so that a test waits for what it says, bounded by a timeout."""

    def __init__(self, proc: subprocess.Popen, name: str) -> None:
        self.proc, self.name = proc, name
        self.lines: list[str] = []
        self.ended = False  # its stdout reached its end
        self._changed = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                self._changed.notify_all()
        with self._changed:
            self.ended = True
            self._changed.notify_all()

    def docs(self) -> list[dict]:
        with self._changed:
            return [json.loads(line) for line in self.lines if line.startswith("{")]

    def expect(self, match: Callable[[dict], bool], timeout: float, what: str) -> dict:
        """The first JSON line that ``match``es (already said, or said within ``timeout`` s)."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                found = next((d for d in (json.loads(x) for x in self.lines if x.startswith("{")) if match(d)), None)
                if found is not None:
                    return found
                left = deadline - time.monotonic()
                if left <= 0 or self.ended:
                    tail = "\n".join(self.lines[-15:])
                    raise AssertionError(f"{self.name}: {what} not seen within {timeout:g} s; it said:\n{tail}")
                self._changed.wait(min(left, 0.5))

    def wait_for_line(self, line: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        with self._changed:
            while line not in self.lines:
                left = deadline - time.monotonic()
                if left <= 0 or self.ended:
                    raise AssertionError(f"{self.name}: {line!r} not seen within {timeout:g} s: {self.lines[-5:]}")
                self._changed.wait(min(left, 0.5))

    def send(self, doc: dict) -> None:
        self.proc.stdin.write(json.dumps(doc) + "\n")
        self.proc.stdin.flush()


class ShopFloor:
    """The network of a ``ShopNetwork`` plan, built on entry and removed on exit, with the
    processes started on its hosts: those are ended (SIGINT, then SIGKILL) before the
    namespaces go, even when building failed half way."""

    def __init__(self, net: ShopNetwork, logs: Path) -> None:
        self.net = net
        self.logs = logs
        self.procs: list[subprocess.Popen] = []
        self.sniffer: Talker | None = None

    def __enter__(self) -> "ShopFloor":
        try:
            for command in setup_commands(self.net):
                subprocess.run(command, check=True, capture_output=True, text=True, timeout=30)
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __getitem__(self, role: str) -> Host:
        return self.net[role]

    def _popen(self, netns: str, argv: list[str], env: dict[str, str], name: str, talk: bool) -> subprocess.Popen:
        self.logs.mkdir(parents=True, exist_ok=True)
        with (self.logs / f"{name}.log").open("w") as log:
            pipes = {"stdin": subprocess.PIPE, "stdout": subprocess.PIPE, "stderr": log, "text": True} if talk \
                else {"stdout": log, "stderr": subprocess.STDOUT}
            proc = subprocess.Popen(["ip", "netns", "exec", netns, *argv], env=env, start_new_session=True, **pipes)
        self.procs.append(proc)
        return proc

    def start(self, role: str, name: str, argv: list[str], env: dict[str, str]) -> subprocess.Popen:
        """Start ``argv`` on the host ``role``; its output goes to ``<logs>/<name>.log``."""
        return self._popen(self.net[role].netns, argv, env, name, talk=False)

    def talker(self, role: str, name: str, argv: list[str], env: dict[str, str]) -> Talker:
        """Start ``argv`` on the host ``role``, talking JSON lines (stderr to the log)."""
        return Talker(self._popen(self.net[role].netns, argv, env, name, talk=True), name)

    def run(self, role: str, argv: list[str], env: dict[str, str], timeout: float) -> subprocess.CompletedProcess:
        """Run ``argv`` on the host ``role`` to its end (``timeout`` only catches a hang)."""
        return subprocess.run(in_host(self.net[role], argv), env=env, capture_output=True, text=True,
                              timeout=timeout)

    def watch(self, argv: list[str], env: dict[str, str], timeout: float = 30) -> None:
        """Start the switch's sniffer (``argv``) and wait until it listens."""
        self.sniffer = Talker(self._popen(self.net.switch, argv, env, "sniffer", talk=True), "sniffer")
        self.sniffer.wait_for_line("ready", timeout)

    def traffic(self) -> dict:
        """Stop the sniffer; what crossed the switch: counts by kind, shop packets by
        source address, and samples of anything foreign."""
        self.stop(self.sniffer.proc, signal.SIGTERM)
        return self.sniffer.expect(lambda d: "counts" in d, 10, "the sniffer's counts")

    def counters(self, role: str) -> dict[str, int]:
        """What the host's link has sent and received so far."""
        host = self.net[role]
        out = subprocess.run(["ip", "-n", host.netns, "-s", "-j", "link", "show", "dev", host.link],
                             check=True, capture_output=True, text=True, timeout=10).stdout
        return link_stats(json.loads(out))

    def link(self, role: str, up: bool) -> None:
        subprocess.run(link_command(self.net[role], up), check=True, capture_output=True, timeout=10)

    def log(self, name: str) -> str:
        path = self.logs / f"{name}.log"
        return path.read_text(errors="replace") if path.exists() else ""

    def stop(self, proc: subprocess.Popen, sig: int = signal.SIGINT, timeout: float = 10.0) -> int:
        """End one process started here (and what it started: its own session)."""
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                pass
            try:
                proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=timeout)
        return proc.returncode

    def close(self) -> None:
        """End every process started here, then delete the namespaces (their devices and
        cables go with them). Deleting a namespace with a process left in it would only
        unmount its name, so the processes go first."""
        for proc in reversed(self.procs):
            self.stop(proc)
        for command in teardown_commands(self.net):
            subprocess.run(command, capture_output=True, timeout=30)
