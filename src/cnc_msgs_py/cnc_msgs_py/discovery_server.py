"""cnc-discovery-server: Fast DDS's own discovery server, run in the foreground.

A thin wrapper for a cell controller's or a server host's installation: it finds the
``fast-discovery-server`` that ships with Fast DDS (the pip wheel's, which needs its
library directories on LD_LIBRARY_PATH, or a ROS install's on PATH), says where it will
listen and which ``ROS_DISCOVERY_SERVER`` the nodes need, and then becomes that program
(exec): signals, output and exit code are the server's own.
"""
from __future__ import annotations

import os
import sys

from .discovery import (DEFAULT_PORT, MAX_SERVER_ID, DiscoveryServer, discovery_server_variable,
                        find_server_program, server_command, server_environment)
from .tool import tool_parser


def main(argv: list[str] | None = None) -> int:
    """cnc-discovery-server: run Fast DDS's discovery server (until Ctrl-C) for nodes on other hosts."""
    parser = tool_parser(
        "cnc-discovery-server", "cnc_msgs_py", description=main.__doc__,
        epilog="Nodes, cnc-submit and cell controllers then find each other through it with "
               "ROS_DISCOVERY_SERVER (the entry's position is the server's --id); tools that list the "
               "whole graph also set ROS_SUPER_CLIENT=TRUE. See docs/shop-floor.md.")
    parser.add_argument("--address", default=None, metavar="A",
                        help="IPv4 address (or host name) to listen on (default: every interface)")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, metavar="P", help=f"UDP port (default {DEFAULT_PORT})")
    parser.add_argument("--id", type=int, default=0, metavar="N",
                        help=f"server id 0..{MAX_SERVER_ID}: its position in ROS_DISCOVERY_SERVER (default 0)")
    args = parser.parse_args(argv)
    try:
        program = find_server_program()
        command = server_command(program, args.id, args.address, args.port)
    except (FileNotFoundError, ValueError) as err:
        print(f"cnc-discovery-server: {err}", file=sys.stderr)
        return 2
    where = f"{args.address or '0.0.0.0 (every interface)'}:{args.port}"
    clients = discovery_server_variable({args.id: DiscoveryServer(args.address or "<this host>", args.port)})
    version = f"Fast DDS {program.version}, " if program.version else ""
    print(f"cnc-discovery-server: server id {args.id} listening on UDPv4 {where} ({version}{program.path})\n"
          f"cnc-discovery-server: clients set ROS_DISCOVERY_SERVER=\"{clients}\"", flush=True)
    os.execve(command[0], command, server_environment(program, os.environ))
    return 0  # not reached: exec replaces this process


if __name__ == "__main__":
    sys.exit(main())
