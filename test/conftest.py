"""Integration tests run real planner and bridge processes over DDS on this host only.

Every test gets ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a ROS_DOMAIN_ID of its own,
so tests (and parallel CI runs on one machine) never hear each other. Several suites run at
once on one host (engineers working side by side) each take a range of their own with
CNC_TEST_DOMAINS=LOW-HIGH (inclusive, within 1..232).
"""
from __future__ import annotations

import itertools
import os

import pytest


def _domain_range() -> range:
    """The domains this run may use: CNC_TEST_DOMAINS=LOW-HIGH, or 1..100."""
    low, _, high = os.environ.get("CNC_TEST_DOMAINS", "1-100").partition("-")
    return range(int(low), int(high) + 1)


_range = _domain_range()
_domains = itertools.count(os.getpid() * 7)


@pytest.fixture(autouse=True)
def local_dds(monkeypatch):
    """A private DDS domain on localhost for each test."""
    domain = _range[next(_domains) % len(_range)]
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    return domain
