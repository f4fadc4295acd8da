"""Tier 2: ``cnc-contour machine home`` calls the interpolator's ``~/home`` (real rclpy, in-process)."""
from __future__ import annotations

import uuid

import pytest

from cnc_contour_control.nodes.interpolator_node import InterpolatorNode
from cnc_contour_control.testing import InProcessNode
from cnc_tools.cli.main import main

pytestmark = pytest.mark.nodes


def test_the_home_button_answers_with_the_interpolators_reason(capsys: pytest.CaptureFixture[str]) -> None:
    """Before any joint state the position is unknown: the button prints the refusal and exits 1."""
    ns = f"/home_{uuid.uuid4().hex[:8]}"
    params = {"axes": ["x", "y"], "program_source": "action", "program_file": "", "home_position_mm": [1.0, 0.0]}
    with InProcessNode(InterpolatorNode, params, namespace=ns):
        code = main(["machine", "home", "--namespace", ns, "--nodes", "interpolator"])
    out = capsys.readouterr().out
    assert code == 1, out
    assert f"{ns}/interpolator/home: REFUSED: home refused: no joint_states yet" in out
