"""Tier 1: ``cnc-contour machine``: which services a button reaches, and its buttons (no ROS graph)."""
from __future__ import annotations

from typing import Any

import pytest

from cnc_tools.cli.machine import ACTIONS, SERVICE_TYPES, panel_services

TRIGGER, SETBOOL = SERVICE_TYPES["reset"], SERVICE_TYPES["enable"]


class Graph:
    """A node's view of the graph's services."""

    def __init__(self, services: list[tuple[str, list[str]]]) -> None:
        self.services = services

    def get_service_names_and_types(self) -> list[tuple[str, list[str]]]:
        return self.services


GRAPH: Any = Graph([
    ("/cnc/plant/reset", [TRIGGER]), ("/cnc/plant/enable", [SETBOOL]),
    ("/cnc/servo_x/reset", [TRIGGER]), ("/cnc/servo_x/enable", [SETBOOL]),
    ("/cnc/servo_x/get_parameters", ["rcl_interfaces/srv/GetParameters"]),
    ("/cnc/interpolator/enable", ["example/srv/Other"]),          # same name, another type: not a latch
    ("/cnc/interpolator/home", [TRIGGER]),
    ("/cnc/run_ab/plant/reset", [TRIGGER]),                        # a node of another namespace below /cnc
    ("/other/plant/reset", [TRIGGER]),
])


@pytest.mark.parametrize(("suffix", "expected"), [
    ("reset", ["/cnc/plant/reset", "/cnc/servo_x/reset"]),
    ("enable", ["/cnc/plant/enable", "/cnc/servo_x/enable"]),
    ("home", ["/cnc/interpolator/home"]),
])
def test_a_button_reaches_the_namespaces_own_nodes_with_the_right_type(suffix: str, expected: list[str]) -> None:
    assert panel_services(GRAPH, "/cnc", suffix) == expected
    assert panel_services(GRAPH, "/cnc/", suffix) == expected


def test_the_buttons_are_the_estop_its_release_and_the_two_services_both_ways() -> None:
    assert {name: (a.estop, a.service, a.data) for name, a in ACTIONS.items()} == {
        "estop": (True, "", None), "release": (False, "", None), "reset": (None, "reset", None),
        "enable": (None, "enable", True), "disable": (None, "enable", False), "home": (None, "home", None)}
    assert all(a.service in ("", *SERVICE_TYPES) for a in ACTIONS.values())
