"""Session-wide test setup: DDS on loopback and a fresh random ROS domain per test session."""
from __future__ import annotations

import os

import pytest


def pytest_configure(config: pytest.Config) -> None:
    """Before any node exists: the loopback DDS policy and this session's own domain."""
    from cnc_tools.runs.dds import apply_loopback_policy, random_domain_id

    apply_loopback_policy(os.environ, random_domain_id())
