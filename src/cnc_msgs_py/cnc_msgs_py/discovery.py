"""DDS discovery settings: where the nodes look for each other, kept as the user chose.

On one computer the tools keep DDS on this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``)
in a domain of their own. On a shop floor the nodes find each other through Fast DDS's
discovery server, configured by ROS's standard variables, which Fast DDS reads itself:

- ``ROS_DISCOVERY_SERVER``: the servers, ``;``-separated; an entry's position is the
  server's id (``--id`` of cnc-discovery-server), an empty position means no server with
  that id: ``198.18.0.1:11811;198.18.0.9:11811`` or ``;198.18.0.9:11811`` (id 1 only).
- ``ROS_SUPER_CLIENT=TRUE``: the participant receives all discovery data, not only what
  its own topics need (tools that list the graph).
- ``FASTRTPS_DEFAULT_PROFILES_FILE``: a Fast DDS XML profile, for anything beyond these.

Nothing here replaces DDS: this module only decides which variables a process started by
our tools gets (``dds_environment``), reads ``ROS_DISCOVERY_SERVER`` to say what it means,
and finds the discovery server that ships with Fast DDS. ROS-free.
"""
from __future__ import annotations

import ipaddress
import os
import shutil
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Mapping

DEFAULT_PORT = 11811  # Fast DDS's default discovery server port (UDP)
DEFAULT_TCP_PORT = 42100  # and over TCP
MAX_SERVER_ID = 255  # the id is one byte of the server's GUID prefix
TRANSPORTS = ("UDPv4", "UDPv6", "TCPv4", "TCPv6")
# What says where a ROS process looks for its peers (kept when our tools start processes).
DDS_VARIABLES = ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS", "ROS_DISCOVERY_SERVER",
                 "ROS_SUPER_CLIENT", "FASTRTPS_DEFAULT_PROFILES_FILE")
LOCAL_PROFILE = Path(__file__).with_name("fastdds_local.xml")  # for simple discovery (see dds_environment)
SERVER_WHEEL = "ros-fastrtps"  # the PyPI wheel of Fast DDS that carries fast-discovery-server
SERVER_PROGRAM = "fast-discovery-server"


@dataclass(frozen=True)
class DiscoveryServer:
    """One discovery server as a client names it: where it listens (address: an IP or a
    host name) and over which transport."""

    address: str
    port: int = DEFAULT_PORT
    transport: str = "UDPv4"

    def __str__(self) -> str:
        """The entry as ROS_DISCOVERY_SERVER spells it."""
        if self.transport == "UDPv4" and ":" not in self.address:
            return f"{self.address}:{self.port}"
        if self.transport == "UDPv6" and _is_ipv6(self.address):
            return f"[{self.address}]:{self.port}"
        return f"{self.transport}:[{self.address}]:{self.port}"


def parse_discovery_servers(value: str) -> dict[int, DiscoveryServer]:
    """The servers named by a ``ROS_DISCOVERY_SERVER`` value, by id (position).

    Entries are ``ADDRESS``, ``ADDRESS:PORT``, ``[IPV6]:PORT`` or ``TRANSPORT:[ADDRESS]:PORT``
    with TRANSPORT one of UDPv4, UDPv6, TCPv4, TCPv6, as Fast DDS reads them.

    Raises:
        ValueError: an entry is malformed (names its position), or no server is named.
    """
    servers: dict[int, DiscoveryServer] = {}
    for server_id, entry in enumerate(value.split(";")):
        entry = entry.strip()
        if not entry:
            continue
        if server_id > MAX_SERVER_ID:
            raise ValueError(f"ROS_DISCOVERY_SERVER: more than {MAX_SERVER_ID + 1} positions")
        try:
            servers[server_id] = _parse_entry(entry)
        except ValueError as err:
            raise ValueError(f"ROS_DISCOVERY_SERVER position {server_id} ({entry!r}): {err}") from None
    if not servers:
        raise ValueError(f"ROS_DISCOVERY_SERVER names no server: {value!r}")
    return servers


def _parse_entry(entry: str) -> DiscoveryServer:
    transport = next((name for name in TRANSPORTS if entry.startswith(name + ":")), None)
    if transport is not None:
        entry = entry[len(transport) + 1:]
    if entry.startswith("["):
        address, bracket, rest = entry[1:].partition("]")
        if not bracket or (rest and not rest.startswith(":")):
            raise ValueError("expected [ADDRESS]:PORT")
        port_text = rest[1:]
    elif entry.count(":") == 1:
        address, _, port_text = entry.partition(":")
    else:  # a name, an IPv4 address, or an IPv6 address without brackets: no port
        address, port_text = entry, ""
    if not address:
        raise ValueError("no address")
    if transport is None:
        transport = "UDPv6" if _is_ipv6(address) else "UDPv4"
    port = DEFAULT_TCP_PORT if transport.startswith("TCP") else DEFAULT_PORT
    if port_text:
        if not port_text.isdigit() or not 0 < int(port_text) < 65536:
            raise ValueError(f"port must be 1..65535, got {port_text!r}")
        port = int(port_text)
    return DiscoveryServer(address=address, port=port, transport=transport)


def _is_ipv6(address: str) -> bool:
    try:
        return ipaddress.ip_address(address).version == 6
    except ValueError:
        return False  # a host name


def discovery_server_variable(servers: Mapping[int, DiscoveryServer]) -> str:
    """The ``ROS_DISCOVERY_SERVER`` value naming ``servers`` (id -> server) at their
    positions: ``{1: s}`` gives ``;s``."""
    if not servers:
        raise ValueError("no servers")
    if min(servers) < 0 or max(servers) > MAX_SERVER_ID:
        raise ValueError(f"server ids must be 0..{MAX_SERVER_ID}")
    return ";".join(str(servers[i]) if i in servers else "" for i in range(max(servers) + 1))


def server_guid_prefix(server_id: int) -> str:
    """The GUID prefix Fast DDS gives the server with this id (``44.53.<id>.5f.45.50.52.4f.53.49.4d.41``,
    "DS" + id + "_EPROSIMA"), which XML profiles name in ``<RemoteServer prefix=...>``."""
    if not 0 <= server_id <= MAX_SERVER_ID:
        raise ValueError(f"server id must be 0..{MAX_SERVER_ID}, got {server_id}")
    return f"44.53.{server_id:02x}.5f.45.50.52.4f.53.49.4d.41"


def dds_environment(environ: Mapping[str, str], domain_id: int | None = None) -> dict[str, str]:
    """The DDS variables for a ROS process our tools start, given the caller's environment.

    What the user set is kept: ``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE``, a
    ``ROS_DISCOVERY_SERVER`` (with which the range is left to DDS: the servers are where to
    look) and ``FASTRTPS_DEFAULT_PROFILES_FILE``. Only what is unset is chosen: the range is
    ``LOCALHOST``, so tests and demos stay on this host, the domain is ``domain_id`` (if
    given), and with simple discovery the profile is LOCAL_PROFILE (more announcements as
    a participant starts: see the file).

    Returns the full environment (a copy of ``environ`` with those set).
    """
    env = dict(environ)
    if not env.get("ROS_AUTOMATIC_DISCOVERY_RANGE") and not env.get("ROS_DISCOVERY_SERVER", "").strip():
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if not env.get("ROS_DOMAIN_ID") and domain_id is not None:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    if not env.get("ROS_DISCOVERY_SERVER", "").strip() and not env.get("FASTRTPS_DEFAULT_PROFILES_FILE"):
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(LOCAL_PROFILE)
    return env


def describe_discovery(environ: Mapping[str, str]) -> str:
    """One line saying how a process with this environment finds its peers (for logs)."""
    domain = environ.get("ROS_DOMAIN_ID") or "0"
    servers = environ.get("ROS_DISCOVERY_SERVER", "").strip()
    if servers:
        role = "super client" if environ.get("ROS_SUPER_CLIENT", "").upper() in ("TRUE", "1") else "client"
        return f"ROS_DOMAIN_ID {domain}, discovery server {role} of {servers}"
    scope = environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE") or "SUBNET"
    peers = environ.get("ROS_STATIC_PEERS", "").strip()
    return f"ROS_DOMAIN_ID {domain}, simple discovery, range {scope}" + (f", static peers {peers}" if peers else "")


# -- the discovery server that ships with Fast DDS ------------------------------------------


@dataclass(frozen=True)
class ServerProgram:
    """Fast DDS's discovery server executable and the library directories it needs."""

    path: Path
    library_dirs: tuple[Path, ...]
    version: str  # Fast DDS's version, or "" when found on PATH


def find_server_program() -> ServerProgram:
    """The ``fast-discovery-server`` of the installed Fast DDS wheel (pip), else the one on
    PATH (a ROS install). The wheel's ELF binary carries an RPATH that does not resolve
    from a virtual environment, so the directories of the wheel's shared libraries (and of
    Fast CDR's) come with it, for LD_LIBRARY_PATH.

    Raises:
        FileNotFoundError: neither is installed.
    """
    try:
        dist = metadata.distribution(SERVER_WHEEL)
    except metadata.PackageNotFoundError:
        dist = None
    if dist is not None:
        files = list(dist.files or [])
        program = next((f for f in files if f.name == SERVER_PROGRAM and f.parent.name == "bin"), None)
        if program is not None and Path(dist.locate_file(program)).exists():
            dirs = {Path(dist.locate_file(f)).resolve().parent for f in files if _shared_library(f.name)}
            try:
                cdr = metadata.distribution("ros-fastcdr")
                dirs |= {Path(cdr.locate_file(f)).resolve().parent for f in cdr.files or [] if _shared_library(f.name)}
            except metadata.PackageNotFoundError:
                pass
            return ServerProgram(Path(dist.locate_file(program)).resolve(), tuple(sorted(dirs)), dist.version)
    found = shutil.which(SERVER_PROGRAM)
    if found:
        return ServerProgram(Path(found), (), "")
    raise FileNotFoundError(f"{SERVER_PROGRAM} not found: install Fast DDS (pip: {SERVER_WHEEL}, "
                            f"ROS: ros-jazzy-fastrtps)")


def _shared_library(name: str) -> bool:
    return name.startswith("lib") and ".so" in name


def server_command(program: ServerProgram, server_id: int, address: str | None, port: int) -> list[str]:
    """The discovery server's command line: id, UDP address (all interfaces if None) and port.

    Not Fast DDS's BACKUP mode (``--backup``): in the 2.14.5 wheel it crashed restoring its
    state after a SIGKILL (docs/shop-floor.md, known limits)."""
    if not 0 <= server_id <= MAX_SERVER_ID:
        raise ValueError(f"--id must be 0..{MAX_SERVER_ID}, got {server_id}")
    if not 0 < port < 65536:
        raise ValueError(f"--port must be 1..65535, got {port}")
    command = [str(program.path), "--server-id", str(server_id)]
    if address:
        command += ["--udp-address", address]
    return [*command, "--udp-port", str(port)]


def server_environment(program: ServerProgram, environ: Mapping[str, str]) -> dict[str, str]:
    """``environ`` with the program's library directories first on LD_LIBRARY_PATH."""
    env = dict(environ)
    if program.library_dirs:
        parts = [str(d) for d in program.library_dirs] + [p for p in env.get("LD_LIBRARY_PATH", "").split(os.pathsep) if p]
        env["LD_LIBRARY_PATH"] = os.pathsep.join(dict.fromkeys(parts))
    return env
