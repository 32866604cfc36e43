"""A shop floor across hosts, stood in for by network namespaces on this computer.

Each test builds a network of its own (shopnet: one namespace per host, a switch between
them, addresses in 198.18.0.0/24 only, IPv6 off) and removes it again, processes first, even
when it fails. The machines' planner and bridge run on their own hosts in simulation; a
cell controller (shop_cell.py, CncClient) on another; they find each other through Fast
DDS's discovery server (cnc-discovery-server) and ROS_DISCOVERY_SERVER, nothing of ours.
Inside the namespaces DDS still uses no multicast (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
clears its multicast locators; a client's only remote peers are its servers), and a sniffer
on the switch checks that every frame that crossed it was IPv4 or ARP between shop addresses.

Every wait is for something a process says (a status, a liveliness change), bounded by a
timeout that only catches a hang.
"""
from __future__ import annotations

import itertools
import json
import os
import signal
import sys
import time
from pathlib import Path

import pytest

from cnc_msgs_py.discovery import DDS_VARIABLES
from cnc_msgs_py.qos import PLANNER_LEASE_S
from cnc_planner.runner import node_command
from shopnet import ShopFloor, existing_namespaces, plan_network, run_tag
from support import BIN

HERE = Path(__file__).resolve().parent
PORT = 11811
FINAL = ("succeeded", "aborted", "canceled", "rejected")
UNREACHABLE_WITHIN_S = PLANNER_LEASE_S + 1.5  # what the docs state: the lease, plus a margin for a busy CPU
_serial = itertools.count()


def move(job_id: str, x_mm: float, feed: float = 3000.0) -> dict:
    """A mill3 job: a feed move along X and a rapid back."""
    return {"schema": "cnc_job/1", "job_id": job_id, "kind": "move", "machine": "mill3",
            "move": [{"linear": {"x": x_mm}, "feed": feed}, {"rapid": {"x": 0.0}}]}


@pytest.fixture
def shop_floor(tmp_path, local_dds):
    """A factory: ``shop_floor(roles)`` builds the network (once per test); it is removed,
    with every process started on it, when the test ends, and no namespace is left behind."""
    made: list[ShopFloor] = []

    def make(roles: list[str]) -> ShopFloor:
        net = plan_network(roles, run_tag(serial=next(_serial)))
        shop = ShopFloor(net, tmp_path / "logs").__enter__()
        made.append(shop)
        shop.watch([sys.executable, str(HERE / "shop_sniffer.py")], dict(os.environ, PYTHONPATH=str(HERE)))
        shop.domain = local_dds  # the test's own domain, inside the namespaces too
        return shop
    yield make
    for shop in made:
        shop.close()
        assert existing_namespaces(shop.net.tag) == [], "namespaces left behind"


def dds_env(shop: ShopFloor, servers: list[str]) -> dict[str, str]:
    """A process's environment on the shop floor: the standard variables only."""
    env = {k: v for k, v in os.environ.items() if k not in DDS_VARIABLES}
    env.update(ROS_DISCOVERY_SERVER=";".join(f"{shop[s].address}:{PORT}" for s in servers),
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(shop.domain))
    return env


def start_server(shop: ShopFloor, role: str, server_id: int, name: str | None = None):
    """cnc-discovery-server on the host ``role``, with none of the clients' DDS variables
    (to a server, ROS_DISCOVERY_SERVER names other servers to link up with)."""
    env = {k: v for k, v in os.environ.items() if k not in DDS_VARIABLES}
    argv = [str(BIN / "cnc-discovery-server"), "--address", shop[role].address, "--port", str(PORT),
            "--id", str(server_id)]
    return shop.start(role, name or role, argv, env)


# The simulated bridge runs as fast as the planner feeds it, and the tests run beside the
# rest of the suite on 2 CPUs: joint_states at 100 Hz of machine time (not 1 kHz) spare the
# CPU, and the bridge waits up to 5 s (not 1 s) for a starved planner's setpoints.
BRIDGE = {"machine": "mill3", "simulation": True, "joint_state_rate": 100.0, "underrun_timeout": 5.0}


def start_machine(shop: ShopFloor, role: str, env: dict[str, str]) -> str:
    """Planner and bridge of one mill on its own host, under /<role>/cnc; the namespace."""
    namespace = f"/{role}/cnc"
    shop.start(role, f"{role}-bridge", node_command("cnc_servo_bridge.bridge_node", namespace, BRIDGE), env)
    shop.start(role, f"{role}-planner", node_command("cnc_planner.planner_node", namespace,
                                                     {"machine": "mill3", "use_sim_time": True}), env)
    return namespace


def start_cell(shop: ShopFloor, role: str, name: str, machines: list[str], env: dict[str, str]):
    cell = shop.talker(role, name, [sys.executable, str(HERE / "shop_cell.py"), *machines], env)
    cell.expect(lambda d: d["event"] == "ready", 60, "ready")
    return cell


def final_status(cell, machine: str, job_id: str, timeout: float) -> dict:
    doc = cell.expect(lambda d: d["event"] == "status" and d["machine"] == machine
                      and d["status"]["job_id"] == job_id and d["status"]["state"] in FINAL, timeout,
                      f"the final status of {job_id} on {machine}")
    return doc


def submit(shop: ShopFloor, role: str, job: dict, namespace: str, env: dict[str, str], tmp_path: Path):
    """cnc-submit on the host ``role``, as a user there would."""
    path = tmp_path / f"{job['job_id']}.json"
    path.write_text(json.dumps(job))
    return shop.run(role, [str(BIN / "cnc-submit"), str(path), "--namespace", namespace, "--timeout", "90"],
                    env, timeout=120)


def assert_only_shop_traffic(shop: ShopFloor, hosts: list[str]) -> dict:
    """Every frame that crossed the switch was IPv4 or ARP between shop addresses, and every
    host named took part."""
    traffic = shop.traffic()
    assert traffic["counts"].get("foreign", 0) == 0, traffic["foreign"]
    assert {shop[h].address for h in hosts} <= set(traffic["sources"]), traffic
    return traffic


def test_jobs_run_on_two_machines_across_hosts_and_the_cell_sees_both(shop_floor, tmp_path):
    shop = shop_floor(["server", "m1", "m2", "cell"])
    start_server(shop, "server", 0)
    env = dds_env(shop, ["server"])
    machines = [start_machine(shop, m, env) for m in ("m1", "m2")]
    cell = start_cell(shop, "cell", "cell", machines, env)
    for i, machine in enumerate(machines, start=1):
        cell.send({"submit": machine, "job": move(f"a{i}", 20.0 * i)})
    finals = [final_status(cell, machine, f"a{i}", 120)["status"] for i, machine in enumerate(machines, start=1)]
    assert [f["state"] for f in finals] == ["succeeded", "succeeded"], finals
    assert all(f["cycle_time_s"] > 0 for f in finals)
    assert "listening on UDPv4 " + shop["server"].address in shop.log("server")

    # cnc-submit from the cell controller's host, with nothing but ROS_DISCOVERY_SERVER set.
    result = submit(shop, "cell", move("b1", 10.0), machines[1], env, tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert json.loads(result.stdout.strip().splitlines()[-1])["state"] == "succeeded"
    assert_only_shop_traffic(shop, ["server", "m1", "m2", "cell"])


def running(cell, machine: str, job_id: str, timeout: float) -> dict:
    return cell.expect(lambda d: d["event"] == "status" and d["machine"] == machine
                       and d["status"]["job_id"] == job_id and d["status"]["state"] == "running", timeout,
                       f"{job_id} running on {machine}")


def never_lost(cell) -> bool:
    return not [d for d in cell.docs() if d["event"] == "reachable" and not d["up"]]


def test_a_discovery_server_restarted_or_crashed_mid_job_disturbs_nothing_and_new_jobs_are_found(
        shop_floor, tmp_path):
    """Once matched, endpoints talk directly: neither a restart of the server nor its crash
    disturbs a running job. After a restart (SIGTERM: the server says goodbye) new
    participants are found through it. After a crash the matches made stay and the cell's
    jobs are accepted; a server back within its clients' lease of the crashed one is taken
    for it, whose relays they have seen, so new participants are not heard until that lease
    has passed (Fast-DDS#2534, docs/shop-floor.md)."""
    shop = shop_floor(["server", "m1", "cell"])
    server = start_server(shop, "server", 0)
    env = dds_env(shop, ["server"])
    machine = start_machine(shop, "m1", env)
    cell = start_cell(shop, "cell", "cell", [machine], env)

    cell.send({"submit": machine, "job": move("long-1", 300.0, feed=900.0)})
    running(cell, machine, "long-1", 120)
    restarted = time.monotonic()
    shop.stop(server, signal.SIGTERM)  # what a service manager's restart does
    server = start_server(shop, "server", 0, name="server-restarted")
    # A new participant (cnc-submit on the cell host) finds the planner through it; its job
    # queues behind long-1.
    result = submit(shop, "cell", move("b1", 10.0), machine, env, tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert json.loads(result.stdout.strip().splitlines()[-1])["state"] == "succeeded"
    final = final_status(cell, machine, "long-1", 120)
    assert final["status"]["state"] == "succeeded" and final["t"] > restarted

    cell.send({"submit": machine, "job": move("long-2", 300.0, feed=900.0)})
    running(cell, machine, "long-2", 120)
    crashed = time.monotonic()
    shop.stop(server, signal.SIGKILL)
    start_server(shop, "server", 0, name="server-after-crash")
    cell.send({"submit": machine, "job": move("a2", 10.0)})  # queued behind long-2
    cell.expect(lambda d: d["event"] == "status" and d["status"]["job_id"] == "a2"
                and d["status"]["state"] == "accepted", 60, "a2 accepted")
    final = final_status(cell, machine, "long-2", 120)
    assert final["status"]["state"] == "succeeded" and final["t"] > crashed
    assert final_status(cell, machine, "a2", 60)["status"]["state"] == "succeeded"
    assert never_lost(cell)
    assert_only_shop_traffic(shop, ["server", "m1", "cell"])


def test_with_two_redundant_discovery_servers_losing_one_is_not_noticed(shop_floor, tmp_path):
    shop = shop_floor(["ds0", "ds1", "m1", "cell"])
    first = start_server(shop, "ds0", 0)
    start_server(shop, "ds1", 1)
    env = dds_env(shop, ["ds0", "ds1"])
    machine = start_machine(shop, "m1", env)
    cell = start_cell(shop, "cell", "cell", [machine], env)
    cell.send({"submit": machine, "job": move("long-1", 300.0, feed=600.0)})
    running(cell, machine, "long-1", 120)
    killed = time.monotonic()
    shop.stop(first, signal.SIGKILL)
    # A new participant finds the planner through the other server alone.
    result = submit(shop, "cell", move("b1", 10.0), machine, env, tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert json.loads(result.stdout.strip().splitlines()[-1])["state"] == "succeeded"
    final = final_status(cell, machine, "long-1", 120)
    assert final["status"]["state"] == "succeeded" and final["t"] > killed, final
    assert never_lost(cell)
    assert_only_shop_traffic(shop, ["ds0", "ds1", "m1", "cell"])


def test_a_machine_cut_off_runs_its_job_on_and_the_cell_learns_the_end_when_it_is_back(shop_floor, tmp_path):
    shop = shop_floor(["server", "m1", "m2", "cell"])
    start_server(shop, "server", 0)
    env = dds_env(shop, ["server"])
    m1, m2 = (start_machine(shop, m, env) for m in ("m1", "m2"))
    cell = start_cell(shop, "cell", "cell", [m1, m2], env)
    tap = start_cell(shop, "m1", "m1-tap", [m1], env)  # a display on the machine itself
    cell.send({"submit": m1, "job": move("long-1", 300.0, feed=300.0)})
    tap.send({"follow": m1, "job_id": "long-1"})
    running(cell, m1, "long-1", 120)
    running(tap, m1, "long-1", 120)  # the display has found the planner before the cut

    cut = time.monotonic()
    shop.link("m1", False)
    lost = cell.expect(lambda d: d["event"] == "reachable" and d["machine"] == m1 and not d["up"],
                       30, "m1 unreachable")
    print(f"unreachable reported {lost['t'] - cut:.2f} s after the cut")
    assert lost["t"] - cut <= UNREACHABLE_WITHIN_S
    ended = final_status(tap, m1, "long-1", 120)  # seen on m1 itself, still cut off
    assert ended["status"]["state"] == "succeeded" and ended["t"] > cut
    assert not [d for d in cell.docs() if d["event"] == "status" and d["status"]["job_id"] == "long-1"
                and d["status"]["state"] in FINAL]  # the cell cannot know yet

    back = time.monotonic()
    shop.link("m1", True)
    cell.expect(lambda d: d["event"] == "reachable" and d["machine"] == m1 and d["up"] and d["t"] > back,
                60, "m1 reachable again")
    learned = final_status(cell, m1, "long-1", 60)
    print(f"final state learned {learned['t'] - back:.2f} s after the link came back")
    assert learned["status"]["state"] == "succeeded"
    cell.send({"submit": m1, "job": move("next-1", 10.0)})
    assert final_status(cell, m1, "next-1", 60)["status"]["state"] == "succeeded"
    assert not [d for d in cell.docs() if d["event"] == "reachable" and d["machine"] == m2 and not d["up"]]
    assert_only_shop_traffic(shop, ["server", "m1", "m2", "cell"])
