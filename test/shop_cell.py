"""A cell controller for the shop-floor tests: one rclpy node, one CncClient per machine.

Run on a host of a shop network (``python shop_cell.py [--graph] /m1/cnc /m2/cnc``). It takes commands
on stdin and reports on stdout, one JSON document a line, so that a test drives it and
waits for what it reports (never for a fixed time):

    in:  {"submit": "/m1/cnc", "job": {...}}     send a job (validated first)
         {"follow": "/m1/cnc", "job_id": "a-1"}  follow a job sent elsewhere
    out: {"t": ..., "event": "ready"}
         {"t": ..., "event": "reachable", "machine": "/m1/cnc", "up": false}
         {"t": ..., "event": "status", "machine": "/m1/cnc", "status": {...}}
         {"t": ..., "event": "error", "machine": ..., "reason": "..."}
         {"t": ..., "event": "graph", "nodes": 25, "planners": 12, "topics": 40}   (--graph: when it changes)

``t`` is time.monotonic(), the same clock in every namespace of this computer, so a test
can put the controller's view next to what it did to the network.
"""
from __future__ import annotations

import json
import queue
import sys
import threading
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor

from cnc_msgs_py.client import CncClient, CncClientError
from cnc_msgs_py.schema import JobError


def say(event: str, **fields) -> None:
    print(json.dumps({"t": time.monotonic(), "event": event, **fields}), flush=True)


def read_commands(commands: queue.Queue) -> None:
    for line in sys.stdin:
        if line.strip():
            commands.put(json.loads(line))
    commands.put(None)  # stdin closed: time to go


def graph(node, clients: dict[str, CncClient]) -> dict[str, int]:
    """What this participant knows of the ROS graph: nodes, planners it could send jobs to,
    topics (all of them only for a super client or with simple discovery)."""
    return {"nodes": len(node.get_node_names_and_namespaces()),
            "planners": sum(client.planner_listening() for client in clients.values()),
            "topics": len(node.get_topic_names_and_types())}


def main(machines: list[str], watch_graph: bool = False) -> int:
    rclpy.init()
    node = rclpy.create_node("shop_cell")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    clients = {}
    for machine in machines:
        client = CncClient(node, machine, executor=executor)
        client.on_progress(lambda status, m=machine: say("status", machine=m, status=status))
        client.on_reachability(lambda up, m=machine: say("reachable", machine=m, up=up))
        clients[machine] = client
    commands: queue.Queue = queue.Queue()
    threading.Thread(target=read_commands, args=(commands,), daemon=True).start()
    say("ready", machines=machines)
    seen: dict[str, int] = {}
    try:
        while True:
            executor.spin_once(timeout_sec=0.05)
            if watch_graph and (now := graph(node, clients)) != seen:
                seen = now
                say("graph", **now)
            try:
                command = commands.get_nowait()
            except queue.Empty:
                continue
            if command is None:
                return 0
            if "follow" in command:
                clients[command["follow"]].follow(command["job_id"])
                continue
            machine = command["submit"]
            try:
                clients[machine].submit(command["job"], connect_timeout=command.get("connect_timeout", 30.0))
                say("submitted", machine=machine, job_id=command["job"]["job_id"])
            except (CncClientError, JobError) as err:
                say("error", machine=machine, reason=str(err))
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    args = sys.argv[1:]
    sys.exit(main([a for a in args if a != "--graph"], watch_graph="--graph" in args))
