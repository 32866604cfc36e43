"""ROS_DISCOVERY_SERVER as Fast DDS reads it, the DDS variables our tools give the processes
they start (a user's choice is kept), and the discovery server that ships with Fast DDS."""
from __future__ import annotations

import os
import subprocess
import sys
from xml.etree import ElementTree

import pytest

from cnc_msgs_py.discovery import (DEFAULT_PORT, DEFAULT_TCP_PORT, LOCAL_PROFILE, DiscoveryServer, dds_environment,
                                   describe_discovery, discovery_server_variable, find_server_program,
                                   parse_discovery_servers, server_command, server_environment,
                                   server_guid_prefix)


def test_positions_are_server_ids_and_empty_positions_are_free():
    servers = parse_discovery_servers("198.18.0.1:11811;;198.18.0.3")
    assert servers == {0: DiscoveryServer("198.18.0.1", 11811), 2: DiscoveryServer("198.18.0.3", DEFAULT_PORT)}
    assert parse_discovery_servers(";198.18.0.9:12000") == {1: DiscoveryServer("198.18.0.9", 12000)}


@pytest.mark.parametrize("entry, server", [
    ("cell-ds", DiscoveryServer("cell-ds", DEFAULT_PORT, "UDPv4")),
    ("cell-ds:9000", DiscoveryServer("cell-ds", 9000, "UDPv4")),
    ("[fd00::1]:9000", DiscoveryServer("fd00::1", 9000, "UDPv6")),
    ("fd00::1", DiscoveryServer("fd00::1", DEFAULT_PORT, "UDPv6")),
    ("TCPv4:[198.18.0.1]", DiscoveryServer("198.18.0.1", DEFAULT_TCP_PORT, "TCPv4")),
    ("TCPv4:[198.18.0.1]:42101", DiscoveryServer("198.18.0.1", 42101, "TCPv4")),
    ("UDPv4:[cell-ds]:9000", DiscoveryServer("cell-ds", 9000, "UDPv4")),
])
def test_every_form_fast_dds_documents_is_read(entry, server):
    assert parse_discovery_servers(entry) == {0: server}


@pytest.mark.parametrize("value", ["198.18.0.1:11811;;TCPv4:[198.18.0.2]:42100", ";[fd00::1]:11811", "a:1;b:2;c:3"])
def test_the_variable_is_written_back_as_read(value):
    assert discovery_server_variable(parse_discovery_servers(value)) == value


@pytest.mark.parametrize("value, says", [
    ("", "names no server"), (";;", "names no server"), ("198.18.0.1:0", "position 0"),
    (";198.18.0.1:http", "position 1"), ("[fd00::1", "expected [ADDRESS]:PORT"), (":11811", "no address"),
])
def test_a_malformed_value_names_its_position(value, says):
    with pytest.raises(ValueError, match=says.replace("[", r"\[")):
        parse_discovery_servers(value)


def test_server_guid_prefix_spells_ds_id_eprosima():
    assert server_guid_prefix(0) == "44.53.00.5f.45.50.52.4f.53.49.4d.41"
    assert server_guid_prefix(17) == "44.53.11.5f.45.50.52.4f.53.49.4d.41"
    with pytest.raises(ValueError):
        server_guid_prefix(256)


def test_without_a_choice_processes_stay_on_this_host_in_the_given_domain():
    env = dds_environment({"PATH": "/bin"}, 17)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and env["ROS_DOMAIN_ID"] == "17"
    assert env["PATH"] == "/bin" and env["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(LOCAL_PROFILE)


def test_the_local_profile_announces_a_starting_participant_for_two_seconds():
    """Read as Fast DDS reads it: its default profile, ten announcements 200 ms apart."""
    ns = {"f": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    participant = ElementTree.parse(LOCAL_PROFILE).getroot().find("f:participant", ns)
    assert participant.get("is_default_profile") == "true"
    announcements = participant.find("f:rtps/f:builtin/f:discovery_config/f:initialAnnouncements", ns)
    assert int(announcements.find("f:count", ns).text) == 10
    assert int(announcements.find("f:period/f:nanosec", ns).text) == 200_000_000


def test_a_ros_process_reads_the_local_profile_without_complaint():
    probe = "import rclpy; rclpy.init(); rclpy.create_node('probe').destroy_node(); rclpy.shutdown()"
    environ = {k: v for k, v in os.environ.items() if k != "FASTRTPS_DEFAULT_PROFILES_FILE"}
    env = dds_environment(environ, 232)  # a user's ROS_DOMAIN_ID kept; the probe only starts and stops a node
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=60)
    assert result.returncode == 0 and "rror" not in result.stderr, result.stderr


@pytest.mark.parametrize("user, kept", [
    ({"ROS_DOMAIN_ID": "5"}, {"ROS_DOMAIN_ID": "5", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}, {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_DOMAIN_ID": "17"}),
    ({"ROS_DISCOVERY_SERVER": "198.18.0.1:11811"},
     {"ROS_DISCOVERY_SERVER": "198.18.0.1:11811", "ROS_AUTOMATIC_DISCOVERY_RANGE": None, "ROS_DOMAIN_ID": "17"}),
    ({"ROS_DISCOVERY_SERVER": "198.18.0.1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": "3"},
     {"ROS_DISCOVERY_SERVER": "198.18.0.1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": "3"}),
])
def test_a_users_choice_is_kept(user, kept):
    env = dds_environment(user, 17)
    for key, value in kept.items():
        assert env.get(key) == value, key


def test_the_log_line_says_how_peers_are_found():
    assert describe_discovery({"ROS_DOMAIN_ID": "4", "ROS_DISCOVERY_SERVER": "198.18.0.1:11811",
                               "ROS_SUPER_CLIENT": "TRUE"}) == \
        "ROS_DOMAIN_ID 4, discovery server super client of 198.18.0.1:11811"
    assert describe_discovery({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}) == \
        "ROS_DOMAIN_ID 0, simple discovery, range LOCALHOST"


def test_the_wheels_server_is_found_and_runs_from_the_venv():
    """The installed ros-fastrtps wheel's binary, with its libraries: --help runs (exit 0)
    and starts no server."""
    program = find_server_program()
    assert program.path.name == "fast-discovery-server" and program.version
    command = server_command(program, 3, "198.18.0.1", 12345)
    assert command[1:] == ["--server-id", "3", "--udp-address", "198.18.0.1", "--udp-port", "12345"]
    env = server_environment(program, {k: v for k, v in os.environ.items() if k != "LD_LIBRARY_PATH"})
    result = subprocess.run([str(program.path), "--help"], env=env, capture_output=True, text=True, timeout=30)
    assert result.returncode == 0, result.stderr
    assert "--server-id" in result.stdout


@pytest.mark.parametrize("server_id, port", [(-1, 11811), (256, 11811), (0, 0), (0, 70000)])
def test_a_server_id_or_port_out_of_range_is_refused(server_id, port):
    with pytest.raises(ValueError):
        server_command(find_server_program(), server_id, None, port)
