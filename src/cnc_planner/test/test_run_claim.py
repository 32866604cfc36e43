"""This host's claim on a namespace in a DDS domain: one run's nodes at a time, refused at
once and by name (no waiting on DDS discovery), free again when the holder ends or dies."""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Iterator

import pytest

from cnc_planner.nodes import Claim, RunError, free_domain

DOMAIN = {"ROS_DOMAIN_ID": "231"}
NS = f"/claim{os.getpid()}/cnc"  # this process's own: suites side by side never meet here


def test_a_second_claim_on_the_namespace_is_refused_with_the_holder():
    first = Claim(DOMAIN, NS)
    try:
        with pytest.raises(RunError) as err:
            Claim(DOMAIN, NS)
        assert str(err.value) == (f"another run (pid {os.getpid()}) already runs nodes at {NS} in ROS_DOMAIN_ID 231 "
                                  "on this host: set ROS_DOMAIN_ID to a free domain")
        Claim(DOMAIN, f"{NS}2").release()  # another machine of the cell
        Claim({"ROS_DOMAIN_ID": "232"}, NS).release()  # another domain
    finally:
        first.release()
    again = Claim(DOMAIN, NS)  # free once released
    again.release()
    assert not again.path.exists()  # no lock file left behind


@contextlib.contextmanager
def _process(code: str, **popen) -> Iterator[subprocess.Popen]:
    """A Python process running ``code``, killed outright (SIGKILL) when the block ends."""
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, **popen)
    try:
        yield proc
    finally:
        proc.kill()
        proc.wait()


def test_a_killed_holder_leaves_the_namespace_free():
    with _process("import sys; from cnc_planner.nodes import Claim; "
                  f"c = Claim({DOMAIN!r}, {NS!r}); print('held', flush=True); sys.stdin.read()",
                  stdout=subprocess.PIPE, text=True) as holder:
        assert holder.stdout.readline() == "held\n"
        with pytest.raises(RunError, match=f"pid {holder.pid}"):
            Claim(DOMAIN, NS)
    Claim(DOMAIN, NS).release()


def test_a_run_without_a_chosen_domain_takes_the_next_free_one(monkeypatch):
    """Two cnc-runs whose pids agree mod 100 would share a domain: the second takes the next."""
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    own = 1 + os.getpid() % 100
    taken = Claim({"ROS_DOMAIN_ID": str(own)}, NS)
    try:
        env, claim = free_domain(NS)
        assert env["ROS_DOMAIN_ID"] == str(1 + own % 100)
        claim.release()
    finally:
        taken.release()
    env, claim = free_domain(NS)
    assert env["ROS_DOMAIN_ID"] == str(own)
    claim.release()


def test_nodes_left_by_a_killed_run_keep_the_namespace_claimed():
    """A run killed outright (SIGKILL) leaves its nodes running: they share its lock, so a
    next run is refused while they live, and goes ahead once they are gone."""
    claim = Claim(DOMAIN, NS)
    with _process("import sys; sys.stdin.read()", pass_fds=claim.fds):
        claim.file.close()  # the run is gone, without releasing
        with pytest.raises(RunError, match=f"pid {os.getpid()}"):
            Claim(DOMAIN, NS)
    Claim(DOMAIN, NS).release()
