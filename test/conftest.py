"""Integration tests run real planner and bridge processes over DDS on this host only.

Every test gets ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a ROS_DOMAIN_ID of its own,
so tests (and parallel CI runs on one machine) never hear each other. Several suites run at
once on one host (engineers working side by side) each take a range of their own with
CNC_TEST_DOMAINS=LOW-HIGH (inclusive, within 1..232).

A user's own DDS settings are kept (cnc_msgs_py.discovery.dds_environment): a
ROS_DOMAIN_ID pins every test to that domain (unless CNC_TEST_DOMAINS is given), and with
ROS_AUTOMATIC_DISCOVERY_RANGE or ROS_DISCOVERY_SERVER set the range is theirs. The shop-floor
tests (test_shop_floor.py) make networks of their own in namespaces instead.
"""
from __future__ import annotations

import itertools
import os

import pytest

from cnc_msgs_py.discovery import dds_environment
from support import domain_range


_range = domain_range()
_domains = itertools.count(os.getpid() * 7)


@pytest.fixture(autouse=True)
def local_dds(monkeypatch):
    """A private DDS domain on localhost for each test (unless the user chose otherwise)."""
    domain = _range[next(_domains) % len(_range)]
    environ = {k: v for k, v in os.environ.items() if k != "ROS_DOMAIN_ID"}
    for key in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID"):
        value = dds_environment(environ, domain).get(key)
        if value is not None:
            monkeypatch.setenv(key, value)
    return domain
