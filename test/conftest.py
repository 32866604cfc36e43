"""Integration tests run real planner and bridge processes over DDS on this host only.

Every test gets ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a ROS_DOMAIN_ID of its own,
so tests (and parallel CI runs on one machine) never hear each other.
"""
from __future__ import annotations

import itertools
import os

import pytest

_domains = itertools.count(1 + (os.getpid() * 7) % 60)


@pytest.fixture(autouse=True)
def local_dds(monkeypatch):
    """A private DDS domain on localhost for each test."""
    domain = next(_domains) % 100 + 1
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    return domain
