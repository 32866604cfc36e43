"""cnc-submit: send a job to running nodes from the shell and follow it to the end.

Validation happens before anything is sent; a bad job or a missing file is one line on
stderr (exit 2), no traceback. Exit 0 if the job succeeded (or was canceled as asked),
1 if it was rejected, aborted or canceled, 3 if no planner answered in time.
``cnc-submit --resume JOB_ID`` resumes a program held at M0/M1 (sent from here or elsewhere)
and follows it to its end or its next hold.
"""
from __future__ import annotations

import json
import os
import sys
from typing import Any, Callable

from . import topics
from .tool import add_program_options, tool_parser

RESUME_HEAR_S = 3.0  # --resume: how long to listen for the job's latest status (kept by the planner)


def main(argv: list[str] | None = None) -> int:
    """cnc-submit JOB: send a job to running CNC nodes and wait for its final status."""
    parser = tool_parser(
        "cnc-submit", "cnc_msgs_py", description=main.__doc__,
        epilog="Exit codes: 0 succeeded (or canceled as asked by --cancel-after; with --resume: held again), "
               "1 rejected, aborted or canceled, 2 bad job or arguments (--resume: the job is not held), 3 no "
               "planner or timeout. The final status (cnc_status/1, JSON) is printed on stdout; progress goes "
               "to stderr. A program held at M0/M1 is followed until it ends: resume it from another shell.")
    parser.add_argument("job", nargs="?", help="job document: a YAML or JSON file, or a G-code program (.ngc)")
    parser.add_argument("--resume", metavar="JOB_ID", help="resume this job, held at a program pause (M0/M1), "
                                                          "and follow it to its end or next hold (no JOB)")
    add_program_options(parser)
    parser.add_argument("--namespace", default=topics.NAMESPACE, help="the nodes' namespace (default /cnc)")
    parser.add_argument("--timeout", type=float, default=600.0, help="wall-clock limit for the job (s)")
    parser.add_argument("--cancel-after", type=float, default=None, metavar="S",
                        help="cancel the job S seconds (wall clock) after sending it")
    args = parser.parse_args(argv)
    if (args.job is None) == (args.resume is None):
        return _fail("give a JOB to send, or --resume JOB_ID (not both)")
    from .client import CncClient, CncClientError  # past the arguments: --help answers without them
    from .discovery import dds_environment
    from .gcode.document import job_from_args
    from .job import load_job
    from .progress import Progress
    from .schema import JobError

    for name in ("timeout", "cancel_after"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            return _fail(f"--{name.replace('_', '-')}: must be > 0 s, got {value:g}")
    try:
        doc = {"job_id": args.resume} if args.resume else load_job(job_from_args(args))
    except JobError as err:
        return _fail(f"{args.job}: {err}" if err.field else str(err))
    # The user's DDS settings as they are (a discovery server on a shop floor); without
    # any, the nodes of this host only.
    os.environ.update(dds_environment(os.environ))

    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions

    # Python's own SIGINT handling: Ctrl-C raises KeyboardInterrupt and the node still
    # works, so the job can be canceled on the way out.
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(f"cnc_submit_{os.getpid()}")
    client = CncClient(node, args.namespace)
    job_id = doc["job_id"]
    shown = Progress(sys.stderr)
    client.on_progress(shown)
    client.on_reachability(_reachability_printer(client.namespace or "/"))
    try:
        if args.resume:
            return _resume(client, job_id, args.timeout, node)
        client.submit(doc)
        print(f"cnc-submit: sent {job_id} to {client.goal_topic}", file=sys.stderr, flush=True)
        if args.cancel_after is not None:
            try:
                final = client.wait(job_id, args.cancel_after)
            except TimeoutError:
                client.cancel(job_id)
                final = None
            final = final or client.wait(job_id, args.timeout)
        else:
            final = client.wait(job_id, args.timeout)
    except (CncClientError, TimeoutError) as err:
        return _fail(str(err), 3, cleanup=lambda: _shutdown(node))
    except (KeyboardInterrupt, ExternalShutdownException):
        try:
            client.cancel(job_id)
        finally:
            _shutdown(node)
        return _fail(f"interrupted: asked the planner to cancel {job_id}", 130)
    getattr(shown, "close", lambda: None)()
    print(json.dumps(final))
    _shutdown(node)
    if final["state"] == "succeeded" or (final["state"] == "canceled" and args.cancel_after is not None):
        return 0
    return 1


def _resume(client: Any, job_id: str, timeout: float, node: Any) -> int:
    """--resume: hear the job's latest status (job_status keeps it), resume it if held, follow it."""
    from .client import CncClientError

    client.wait_for_planner()
    client.hear(job_id, RESUME_HEAR_S)
    try:
        client.resume(job_id)
    except CncClientError as err:
        return _fail(str(err), 2, cleanup=lambda: _shutdown(node))
    print(f"cnc-submit: resumed {job_id} on {client.resume_topic}", file=sys.stderr, flush=True)
    final = client.wait(job_id, timeout, held=True)
    print(json.dumps(final))
    _shutdown(node)
    return 0 if final["state"] in ("succeeded", "held") else 1


def _reachability_printer(namespace: str) -> Callable[[bool], None]:
    """Say on stderr when the planner is lost (its host cut off: the job runs on there) and
    found again; being found the first time is no news."""
    from .qos import PLANNER_LEASE_S

    lost = False

    def show(reachable: bool) -> None:
        nonlocal lost
        if not reachable:
            lost = True
            print(f"cnc-submit: the planner at {namespace} is unreachable (not heard for {PLANNER_LEASE_S:g} s); "
                  f"a running job runs on there, waiting for word", file=sys.stderr, flush=True)
        elif lost:
            print(f"cnc-submit: the planner at {namespace} is reachable again", file=sys.stderr, flush=True)
    return show


def _shutdown(node: Any) -> None:
    import rclpy

    node.destroy_node()
    rclpy.try_shutdown()


def _fail(message: str, code: int = 2, cleanup: Callable[[], None] | None = None) -> int:
    if cleanup is not None:
        cleanup()
    print(f"cnc-submit: {message}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
