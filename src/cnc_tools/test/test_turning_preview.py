"""The preview in the run: the program's depth schedule reaches the regulator and cuts the overshoot (tier 1)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.force.preview_settings import PreviewSettings
from cnc_contour_control.force.settings import ForceRegulatorSettings
from cnc_tools.analysis.force import force_figures
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[3]
TURNING = ROOT / "scenarios" / "paper004_turning.yaml"
STEPS = [[0.0, 1.0], [1.5, 2.0]]
SHORT: dict[str, Any] = {"duration_s": 2.5, "plant": {"cutting": {"depth_schedule": STEPS}}}


def turning(preview: dict[str, Any] | None = None) -> Scenario:
    """The paper-004 run cut to 2.5 s, one depth step 1 -> 2 mm at 1.5 s, with ``preview`` if given."""
    changes = {**SHORT, "force_regulator": {"preview": preview}} if preview is not None else SHORT
    return load_scenario(TURNING, changes)


def overshoot_pct(scenario: Scenario) -> float:
    figures = force_figures(run_engine(scenario), 500.0)
    assert figures is not None and [s.start_s for s in figures.segments] == [0.0, 1.5]
    overshoot = figures.segments[1].overshoot_pct
    assert overshoot is not None
    return overshoot


def test_the_right_schedule_cuts_the_overshoot_at_the_depth_step() -> None:
    feedback = overshoot_pct(turning())
    previewed = overshoot_pct(turning({"depth_schedule": STEPS}))
    assert feedback > 35.0, "feedback alone cannot beat the floor (39 % from 500 N)"
    assert previewed < 10.0 and previewed < feedback / 4.0


def test_the_engine_stage_applies_the_plans_the_settings_make() -> None:
    scenario = turning({"depth_schedule": STEPS})
    settings = scenario.force_regulator
    assert settings is not None and settings.preview.enabled
    (plan,) = settings.make().plans
    assert plan.start_s == pytest.approx(1.5 - settings.preview.window.before_s)
    run = run_engine(scenario)
    assert run.feed_override is not None
    t_s = run.feed_override.stamp_ns * 1e-9 + scenario.sample_time_s     # the regulator's clock: one tick on
    inside = (t_s > plan.start_s + 1e-6) & (t_s < plan.end_s - 1e-6)
    planned = [plan.ratio_at(t + 1e-9) for t in t_s[inside]]
    assert run.feed_override.applied_ratio[inside].tolist() == planned


def test_without_the_section_there_are_no_plans_and_the_graph_gets_the_same_settings(tmp_path: Path) -> None:
    assert turning().force_regulator is not None and turning().force_regulator.make().plans == ()
    scenario = turning({"depth_schedule": STEPS, "model": {"interpolator_tau_s": 0.2}})
    specs = {spec.name: spec.parameters for spec in graph_specs(scenario, tmp_path, extra_subscribers=1)}
    given = specs["force_regulator"]["preview"]
    assert PreviewSettings(**given) == scenario.force_regulator.preview
    assert given["enabled"] is True and given["depth_schedule_t_s"] == [0.0, 1.5]


@pytest.mark.parametrize(("preview", "message"), [
    ({"depth_schedule": [[0.0, 1.0], [0.0, 2.0]]}, "preview.depth_schedule[1].t_s must be > 0.0 (sorted), got 0.0"),
    ({"depth_schedule": [[0.0, -1.0]]}, "depth_schedule[0].depth_mm"),
    ({"depth_schedule": [[0.0]]}, "preview.depth_schedule must be a list of [t_s, depth_mm] pairs"),
    ({"horizon_s": 1.0}, "preview.horizon_s: unknown key"),
    ({"window": {"before_s": -1.0}}, "before_s"),
    ({"depth_schedule": [[True, 1.0]]}, "preview.depth_schedule_t_s[0] must be a number, got True"),
    ({"depth_schedule": [[0.0, None]]}, "preview.depth_schedule_mm[0] must be a number, got None"),
    ({"depth_schedule": [[0.0, float("nan")]]}, "preview.depth_schedule_mm[0] must be finite"),
])
def test_a_bad_preview_is_refused_naming_the_value(preview: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        ForceRegulatorSettings.from_mapping({"preview": preview})
    assert message in str(err.value)
