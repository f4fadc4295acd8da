"""The PDC estimating f_d on line with no spindle schedule: >= 90 % of the f_d line removed for any spindle
deviation within ±7 % (engine runs of the paper-002 circle, the servo commanding 1500 rpm)."""
from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from cnc_tools.reproductions.paper002 import data
from cnc_tools.reproductions.paper002.runs import PDC_LAWS, Case, run_case
from cnc_tools.reproductions.paper002.tracked import GOAL_TRACKED_REMOVAL

ROOT = Path(__file__).resolve().parents[3]
#: Circle length of each run [s] (the tracker settles in about 0.3 s).
RUN_S = 2.0


@pytest.fixture(autouse=True)
def project_root(monkeypatch: pytest.MonkeyPatch) -> None:
    """The runs find the scenario under CNC_CONTOUR_ROOT."""
    monkeypatch.setenv("CNC_CONTOUR_ROOT", str(ROOT))


@settings(max_examples=5, deadline=None, phases=(Phase.explicit, Phase.generate),  # two engine runs each
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(deviation=st.floats(-0.07, 0.07), law=st.sampled_from(PDC_LAWS))
def test_the_tracking_pdc_removes_the_line_at_any_spindle_deviation(deviation: float, law: str) -> None:
    rpm = data.SPINDLE_RPM * (1.0 + deviation)
    bare = run_case(Case("t/p", "circle", "p", plant_rpm=rpm, duration_s=RUN_S)).measure.fd_pulse
    tracked = run_case(Case(f"t/{law}", "circle", law, plant_rpm=rpm, duration_s=RUN_S, track=True)).measure.fd_pulse
    assert 1.0 - tracked / bare >= GOAL_TRACKED_REMOVAL, (deviation, law, tracked, bare)
