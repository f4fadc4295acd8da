"""The turning run in the engine: the plant's force, the regulator's override, the loop's one-tick delay (tier 1)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.force import force_law_config
from cnc_contour_control.force.settings import ForceRegulatorSettings
from cnc_plant_sim.models.plant import make_plant
from cnc_plant_sim.process.cutting import CuttingConfig, cutting_force_n
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import run_engine, tick_count
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[3]
TURNING = ROOT / "scenarios" / "paper004_turning.yaml"
SHORT = {"duration_s": 1.0, "plant": {"cutting": {"depth_schedule": [[0.0, 1.0], [0.5, 2.0]]}}}


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return load_scenario(TURNING, SHORT)


@pytest.fixture(scope="module")
def run(scenario: Scenario) -> RunRecord:
    return run_engine(scenario)


def test_the_turning_pipeline_has_the_force_loop_per_tick(scenario: Scenario, run: RunRecord) -> None:
    stages = scenario.pipeline()
    assert stages.names == ("plant", "interpolator", "servo", "force_regulator")
    assert {"cutting_force", "feed_override"} <= set(stages.per_tick_topics())
    assert stages.readers("cutting_force") == ("force_regulator",) and stages.readers("feed_override") == (
        "interpolator",)
    assert run.cutting_force is not None and run.feed_override is not None
    assert run.cutting_force.force_n.shape == (tick_count(scenario), 3) == (run.ticks, 3)
    assert (run.cutting_force.force_n[:, 1:] == 0.0).all() and (run.cutting_force.torque_n_m == 0.0).all()


def test_the_recorded_force_is_the_plants_under_the_recorded_commands(scenario: Scenario, run: RunRecord) -> None:
    plant = make_plant(scenario.plant)
    plant.reset(list(scenario.program.start_m))
    forces = []
    for commands in run.command_array().tolist():
        forces.append(cutting_force_n(plant))
        plant.step(commands, scenario.sample_time_s)
    assert run.cutting_force is not None and run.cutting_force.force_n[:, 0].tolist() == forces
    assert max(forces) > 400.0, "the tool cut"


def test_the_override_is_the_core_regulators_on_the_recorded_force(scenario: Scenario, run: RunRecord) -> None:
    assert scenario.force_regulator is not None and run.cutting_force is not None and run.feed_override is not None
    regulator, reference_n = scenario.force_regulator.make(), scenario.force_regulator.setpoint.reference_n
    samples = [regulator.step(scenario.sample_time_s, f, reference_n) for f in run.cutting_force.force_n[:, 0]]
    assert run.feed_override.requested_ratio.tolist() == [s.requested_ratio for s in samples]
    assert run.feed_override.applied_ratio.tolist() == [s.applied_ratio for s in samples]
    assert len(set(run.feed_override.applied_ratio.tolist())) > 2, "the override moved"


def test_the_interpolator_takes_the_previous_ticks_override(scenario: Scenario, run: RunRecord) -> None:
    assert run.feed_override is not None and run.reference is not None
    live = scenario.make_live_reference()
    requests = [1.0, *run.feed_override.applied_ratio[:-1].tolist()]   # tick 0: none yet; tick k: k-1's
    samples = [live.step(int(s), live.request(int(s), r)) for s, r in zip(run.reference.stamp_ns, requests)]
    assert run.reference.position_m.tolist() == [s.position_m.tolist() for s in samples]
    assert run.reference.feed_override_ratio is not None
    assert run.reference.feed_override_ratio.tolist() == [s.feed_override_ratio for s in samples]


def test_the_force_and_override_go_to_a_bag_and_come_back(run: RunRecord, tmp_path: Path) -> None:
    from cnc_tools.bagio.bag import read_bag
    from cnc_tools.bagio.record_bag import write_record_bag

    back = read_bag(write_record_bag(run, tmp_path / "bag"))
    assert back.integrity.complete and back.cutting_force is not None and back.feed_override is not None
    assert run.cutting_force is not None and run.feed_override is not None
    assert_allclose(back.cutting_force.force_n, run.cutting_force.force_n, rtol=0, atol=0)
    assert_allclose(back.feed_override.applied_ratio, run.feed_override.applied_ratio, rtol=0, atol=0)


def test_the_programmed_feed_is_the_programs_before_the_override(run: RunRecord, tmp_path: Path) -> None:
    from cnc_tools.bagio.bag import read_bag
    from cnc_tools.bagio.record_bag import write_record_bag

    ref = run.reference
    assert ref is not None and ref.programmed_feed_m_s is not None and ref.feed_override_ratio is not None
    assert set(ref.programmed_feed_m_s.tolist()) == {0.12 / 60.0}, "120 mm/min, whatever the override"
    assert (ref.feed_override_ratio != 1.0).any() and (ref.feed_m_s != ref.programmed_feed_m_s).any()
    back = read_bag(write_record_bag(run, tmp_path / "bag")).reference
    assert back is not None and back.programmed_feed_m_s is not None
    assert back.programmed_feed_m_s.tolist() == ref.programmed_feed_m_s.tolist()


def test_the_graphs_parameters_are_the_configs_values(scenario: Scenario, tmp_path: Path) -> None:
    specs = {spec.name: spec.parameters for spec in graph_specs(scenario, tmp_path, extra_subscribers=1)}
    plant, regulator = specs["plant"], specs["force_regulator"]
    assert CuttingConfig.from_mapping(plant["cutting"]) == scenario.plant.cutting
    assert plant["cutting"]["depth_schedule_t_s"] == [0.0, 0.5]
    assert plant["cutting_force_subscribers"] == 2, "the regulator and the recorder"
    assert regulator["required_readers"] == ["interpolator"] and regulator["min_subscribers"] == 2
    lockstep = ("sample_time_s", "input_timeout_s", "startup_timeout_s", "min_subscribers", "required_readers")
    settings = ForceRegulatorSettings.from_mapping({k: v for k, v in regulator.items() if k not in lockstep})
    given = scenario.force_regulator
    assert given is not None and settings.setpoint == given.setpoint
    assert settings.values() == given.values(), "the law's config completed with its defaults, nothing renamed"
    assert force_law_config(settings.regulator.law, settings.regulator.law_params) == force_law_config(
        given.regulator.law, given.regulator.law_params)
    assert specs["interpolator"]["feed_override_source"] == "previous_tick"


@pytest.mark.parametrize(("changes", "message"), [
    ({"plant": {"cutting": {"process": "none"}}}, "scenario.force_regulator regulates the cutting force"),
    ({"feed_override": {"max_ratio": 1.2}}, "quantiser.max_ratio must be <= feed_override.max_ratio (1.2), got 1.5"),
    ({"force_regulator": {"reference_n": -5.0}}, "reference_n must be in [0.001, 10000000.0], got -5.0"),
    ({"force_regulator": {"gain": 1.0}}, "scenario.force_regulator.gain: unknown key"),
    ({"force_regulator": {"law": "bang"}}, "force_law must be one of"),
    ({"feed_override": {"schedule": [[0.0, 0.5]]}}, "feed_override.schedule and the force_regulator"),
])
def test_a_bad_force_loop_is_refused_naming_the_option(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        load_scenario(TURNING, changes)
    assert message in str(err.value)


def test_the_score_shows_the_force_figures_per_depth_segment(run: RunRecord) -> None:
    from cnc_tools.analysis.scoring import score_run

    score = score_run(run, force_reference_n=500.0)
    assert score.force is not None and run.cutting_force is not None
    first, second = score.force.segments
    force, t_s = run.cutting_force.force_n[:, 0], run.time_s
    assert (first.start_s, first.depth_mm, second.start_s, second.depth_mm) == (0.0, 1.0, 0.5, 2.0)
    assert second.peak_n == force[t_s >= 0.5].max() and first.peak_n == force[t_s < 0.5].max()
    assert second.overshoot_pct == pytest.approx(100.0 * (second.peak_n / 500.0 - 1.0))
    assert second.peak_n > 550.0 and second.settling_s is not None and 0.0 < second.settling_s < 0.5
    assert score.to_dict()["cutting_force"]["segments"][1]["peak_n"] == second.peak_n
    assert "overshoot %" in score.to_table()
    bare = score_run(run)
    assert bare.force is not None and bare.force.segments[1].overshoot_pct is None, "no reference: no overshoot"
