"""A shop floor of 12 simulated mills over 4 machine hosts, in network namespaces (root);
and of 6 over 2, to see how the figures scale.

Six namespaces stand in for computers (test/shopnet.py): a discovery-server host, four
machine controllers with three mills each (a planner and a bridge per mill, simulation,
under /h<i>m<j>/cnc) and a cell controller (test/shop_cell.py, one CncClient per mill).
Run twice, alike but for discovery:

- discovery server: cnc-discovery-server on its host, every process a client of it
  (ROS_DISCOVERY_SERVER), a super client (ROS_SUPER_CLIENT=TRUE) beside the cell to list
  the whole graph;
- simple discovery, unicast: no server, ROS_STATIC_PEERS naming the hosts and a Fast DDS
  XML profile that lets a participant reach 12 peers per address (default 4), so that
  the 6 participants of a machine host find each other (no multicast: none may leave the
  namespaces).

Measured: the time from starting the 24 nodes to the cell controller's full graph (24
nodes and 12 planners it can send jobs to), the packets on the server's interface and
through the switch (every host's link, sent) until then and while the jobs run, and the
result of one job per mill, all sent at once. Writes bench/results/shop_floor.txt; about
8 minutes on 2 CPUs. Not part of `make bench` (it needs root): `make bench-shop`.
"""
from __future__ import annotations

import json
import os
import re
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src" / p) for p in ("cnc_msgs_py", "cnc_analysis", "cnc_planner", "cnc_servo_bridge")]
sys.path.insert(0, str(ROOT / "test"))

from cnc_msgs_py.discovery import DDS_VARIABLES  # noqa: E402
from cnc_planner.runner import node_command  # noqa: E402
from publish import write_result  # noqa: E402
from shopnet import ShopFloor, plan_network, run_tag  # noqa: E402

HOSTS, PER_HOST = 4, 3  # the cell of the issue; also run on 2 hosts, to see how the figures scale
BIN = Path(sys.executable).parent
PORT = 11811
DOMAIN = 57
FINAL = ("succeeded", "aborted", "canceled", "rejected")
PEERS_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds>
  <profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>udp_12_peers</transport_id>
        <type>UDPv4</type>
        <maxInitialPeersRange>12</maxInitialPeersRange>
      </transport_descriptor>
      <transport_descriptor>
        <transport_id>shm</transport_id>
        <type>SHM</type>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="shop_simple_unicast" is_default_profile="true">
      <rtps>
        <userTransports>
          <transport_id>udp_12_peers</transport_id>
          <transport_id>shm</transport_id>
        </userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
      </rtps>
    </participant>
  </profiles>
</dds>
"""
UP_LINES = ("active: drives enabled", "planning for machine")  # a bridge, a planner ready (their logs)


def job(job_id: str) -> dict:
    return {"schema": "cnc_job/1", "job_id": job_id, "kind": "move", "machine": "mill3",
            "move": [{"linear": {"x": 50.0}, "feed": 3000.0}, {"rapid": {"x": 0.0}}]}


def machines(hosts: int) -> list[tuple[str, str]]:
    """(host, namespace) of every mill."""
    return [(f"h{h}", f"/h{h}m{m}/cnc") for h in range(1, hosts + 1) for m in range(1, PER_HOST + 1)]


def up_time(log: str) -> float | None:
    """The wall time (epoch s) a node said it is ready, from its ROS log line."""
    for line in log.splitlines():
        if any(up in line for up in UP_LINES):
            found = re.search(r"\[(\d+\.\d+)\]", line)
            return float(found.group(1)) if found else None
    return None


def switch_packets(shop: ShopFloor, roles: list[str]) -> int:
    return sum(shop.counters(r)["tx_packets"] for r in roles)


def run(mode: str, hosts: int, out: Path) -> dict:
    roles = ["server", *(f"h{h}" for h in range(1, hosts + 1)), "cell"]
    shop = ShopFloor(plan_network(roles, run_tag(serial=len(mode) + hosts)), out / f"{mode.replace(' ', '_')}_{hosts}")
    with shop:
        env = {k: v for k, v in os.environ.items() if k not in DDS_VARIABLES}
        env.update(ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_DOMAIN_ID=str(DOMAIN))
        if mode == "discovery server":
            shop.start("server", "server", [str(BIN / "cnc-discovery-server"), "--address", shop["server"].address,
                                            "--port", str(PORT)], dict(env))
            env["ROS_DISCOVERY_SERVER"] = f"{shop['server'].address}:{PORT}"
        else:
            profile = out / "simple_unicast.xml"
            profile.write_text(PEERS_PROFILE)
            env.update(ROS_STATIC_PEERS=";".join(shop[r].address for r in roles if r != "server"),
                       FASTRTPS_DEFAULT_PROFILES_FILE=str(profile))
        before = {r: shop.counters(r) for r in roles}
        started, started_wall = time.monotonic(), time.time()  # monotonic: one clock for every namespace
        for host, namespace in machines(hosts):
            name = namespace.strip("/").split("/")[0]
            shop.start(host, f"{name}-bridge", node_command("cnc_servo_bridge.bridge_node", namespace,
                                                            {"machine": "mill3", "simulation": True}), env)
            shop.start(host, f"{name}-planner", node_command("cnc_planner.planner_node", namespace,
                                                             {"machine": "mill3", "use_sim_time": True}), env)
        namespaces = [ns for _, ns in machines(hosts)]
        cell = shop.talker("cell", "cell", [sys.executable, str(ROOT / "test" / "shop_cell.py"), "--graph",
                                            *namespaces], env)
        lister = None
        if mode == "discovery server":  # a tool that lists the graph
            lister = shop.talker("cell", "lister", [sys.executable, str(ROOT / "test" / "shop_cell.py"), "--graph"],
                                 dict(env, ROS_SUPER_CLIENT="TRUE"))
        nodes = 2 * len(namespaces)
        full = cell.expect(lambda d: d["event"] == "graph" and d["planners"] == len(namespaces)
                           and d["nodes"] >= nodes, 600, "the full graph")
        at_full = switch_packets(shop, roles), shop.counters("server")
        ups = [up_time(shop.log(f"{ns.strip('/').split('/')[0]}-{kind}")) for ns in namespaces
               for kind in ("bridge", "planner")]
        last_up = max(u for u in ups if u is not None)  # the nodes log the wall clock
        topics = {"cell": full["topics"]}
        if lister is not None:
            lister.expect(lambda d: d["event"] == "graph" and d["nodes"] >= nodes + 1, 120, "the lister's graph")
            topics["super client"] = max(d["topics"] for d in lister.docs() if d["event"] == "graph")
            topics["cell"] = max(d["topics"] for d in cell.docs() if d["event"] == "graph")

        sent = time.monotonic()
        for i, namespace in enumerate(namespaces):
            cell.send({"submit": namespace, "job": job(f"j{i + 1:02d}")})
        finals = []
        for i, namespace in enumerate(namespaces):
            doc = cell.expect(lambda d, j=f"j{i + 1:02d}": d["event"] == "status" and d["status"]["job_id"] == j
                              and d["status"]["state"] in FINAL, 600, f"j{i + 1:02d} final")
            finals.append({"machine": namespace, "job_id": doc["status"]["job_id"], "state": doc["status"]["state"],
                           "cycle_time_s": doc["status"].get("cycle_time_s", 0.0), "wall_s": doc["t"] - sent})
        at_end = switch_packets(shop, roles), shop.counters("server")
        base_switch = sum(before[r]["tx_packets"] for r in roles)
        server_base = before["server"]["rx_packets"] + before["server"]["tx_packets"]
        return {
            "mode": mode, "mills": len(namespaces), "hosts": hosts,
            "full_graph_s": full["t"] - started, "last_node_up_s": last_up - started_wall,
            "switch_packets_discovery": at_full[0] - base_switch,
            "server_packets_discovery": at_full[1]["rx_packets"] + at_full[1]["tx_packets"] - server_base,
            "switch_packets_total": at_end[0] - base_switch,
            "server_packets_total": at_end[1]["rx_packets"] + at_end[1]["tx_packets"] - server_base,
            "topics": topics, "jobs": finals,
        }


def table(results: list[dict]) -> str:
    lines = [f"# bench/shop_floor.py: simulated mills ({PER_HOST} per host, a planner and a bridge each), a cell "
             f"controller host and a server host, in network namespaces on {os.cpu_count()} CPUs",
             "", "| mills (hosts) | discovery | last node up (s) | full graph (s) | after the last node (s) "
             "| packets through the switch until then | of them on the server's interface "
             "| switch, whole run | server, whole run | topics seen |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        topics = ", ".join(f"{k} {v}" for k, v in r["topics"].items())
        ds = r["mode"] == "discovery server"
        server = (r["server_packets_discovery"], r["server_packets_total"]) if ds else ("-", "-")
        lines.append(f"| {r['mills']} ({r['hosts']}) | {r['mode']} | {r['last_node_up_s']:.1f} | {r['full_graph_s']:.1f} "
                     f"| {r['full_graph_s'] - r['last_node_up_s']:.1f} | {r['switch_packets_discovery']} | {server[0]} "
                     f"| {r['switch_packets_total']} | {server[1]} | {topics} |")
    for r in results:
        if r["hosts"] != HOSTS:
            continue
        lines += ["", f"jobs, {r['mills']} mills ({r['mode']}): one per mill, all sent at once",
                  "", "| mill | job | state | cycle time (s) | wall time from sending (s) |", "|---|---|---|---|---|"]
        lines += [f"| {j['machine']} | {j['job_id']} | {j['state']} | {j['cycle_time_s']:.3f} | {j['wall_s']:.1f} |"
                  for j in r["jobs"]]
    return "\n".join(lines)


def main() -> int:
    out = Path(os.environ.get("SHOP_BENCH_OUT", "/tmp")) / f"shop_floor_{os.getpid()}"
    out.mkdir(parents=True, exist_ok=True)
    results = [run(mode, hosts, out) for hosts in (2, HOSTS) for mode in ("discovery server", "simple")]
    (out / "results.json").write_text(json.dumps(results, indent=2))
    text = table(results)
    print(text)
    print(f"kept: {write_result('shop_floor.txt', text)} (logs in {out})")
    return 0 if all(j["state"] == "succeeded" for r in results for j in r["jobs"]) else 1


if __name__ == "__main__":
    sys.exit(main())
