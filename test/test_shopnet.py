"""The plan of a shop network (no root needed): names, addresses, the commands that build
it touch no root-namespace device, and what the switch's sniffer counts as foreign."""
from __future__ import annotations

import ipaddress

import pytest

from shopnet import SUBNET, classify_frame, link_stats, plan_network, run_tag, setup_commands, teardown_commands


def test_hosts_get_shop_addresses_in_order_and_short_unique_names():
    net = plan_network(["server", "m1", "cell"], run_tag(pid=123456, serial=7))
    assert [h.address for h in net.hosts.values()] == ["198.18.0.1", "198.18.0.2", "198.18.0.3"]
    assert all(ipaddress.ip_address(h.address) in SUBNET for h in net.hosts.values())
    names = [n for h in net.hosts.values() for n in (h.link, h.port)] + [net.bridge]
    assert len(set(names)) == len(names) and all(len(n) <= 15 for n in names)  # IFNAMSIZ
    assert net.tag == "cs2345607" and net["m1"].netns == "cs2345607-m1"
    with pytest.raises(ValueError):
        plan_network(["m1", "m1"], "x")


def test_every_device_is_made_inside_a_namespace_and_ipv6_is_off():
    net = plan_network(["server", "m1"], "t1")
    commands = setup_commands(net)
    namespaces = {net.switch, *(h.netns for h in net.hosts.values())}
    for command in commands:
        if command[:3] == ["ip", "netns", "add"]:
            continue
        assert command[:2] in (["ip", "-n"], ["ip", "netns"]) and (command[2] in namespaces or command[3] in namespaces)
        if "veth" in command:  # both ends placed in namespaces as they are made
            assert command[command.index("netns", 4) + 1] in namespaces
    assert sum("disable_ipv6=1" in c[-1] for c in commands) == 2 * len(namespaces)
    assert {c[-1] for c in teardown_commands(net)} == namespaces


def ipv4(src: str, dst: str) -> bytes:
    return bytes(12) + b"\x08\x00" + bytes(9) + b"\x11" + bytes(2) + \
        ipaddress.ip_address(src).packed + ipaddress.ip_address(dst).packed


def test_only_ipv4_and_arp_between_shop_addresses_are_shop_traffic():
    assert classify_frame(ipv4("198.18.0.2", "198.18.0.1")) == ("shop", "198.18.0.2")
    assert classify_frame(ipv4("198.18.0.2", "239.255.0.1"))[0] == "foreign"  # DDS multicast
    assert classify_frame(ipv4("198.18.0.2", "10.0.0.1"))[0] == "foreign"
    arp = bytes(12) + b"\x08\x06" + bytes(14) + ipaddress.ip_address("198.18.0.2").packed + bytes(6) + \
        ipaddress.ip_address("198.18.0.1").packed
    assert classify_frame(arp) == ("arp", "198.18.0.2")
    assert classify_frame(bytes(12) + b"\x86\xdd" + bytes(40))[0] == "foreign"  # IPv6


def test_link_stats_reads_ip_s_j():
    doc = [{"stats64": {"rx": {"packets": 3, "bytes": 300}, "tx": {"packets": 4, "bytes": 400}}}]
    assert link_stats(doc) == {"rx_packets": 3, "rx_bytes": 300, "tx_packets": 4, "tx_bytes": 400}
