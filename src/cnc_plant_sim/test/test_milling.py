"""The milling process: closed-form mean against the teeth summed, the tooth-passing part, the plant section (core)."""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.force_model import DepthSchedule
from cnc_plant_sim.models.plant import PlantConfig, make_plant
from cnc_plant_sim.process.cutting import CUTTING_PROCESSES, CuttingConfig, cutting_force_n
from cnc_plant_sim.process.milling import MillingConfig, MillingProcess, instant_force, mean_force_vectors

MILLING: dict[str, Any] = {"process": "milling", "depth_schedule": [[0.0, 1.0], [0.05, 2.0]],
                           "milling": {"flutes": 4, "feed_axes": ["x", "y"]}}


def tooth_period_mean(config: MillingConfig, chip_mm: float, depth_mm: float, samples: int = 8000) -> np.ndarray:
    """The mean of the summed tooth forces over one tooth period, by the midpoint rule."""
    pitch = 2.0 * math.pi / config.flutes
    angles = pitch * (np.arange(samples) + 0.5) / samples
    return np.mean([instant_force(config, a, chip_mm, depth_mm) for a in angles], axis=0)


@pytest.mark.parametrize("immersion", ["down", "up"])
@pytest.mark.parametrize(("radial_depth_mm", "flutes"), [(1.0, 2), (5.0, 3), (5.0, 4), (10.0, 2), (7.5, 5)])
def test_the_closed_form_mean_is_the_teeth_summed_over_a_pass(immersion: str, radial_depth_mm: float,
                                                              flutes: int) -> None:
    config = MillingConfig(radial_engagement=radial_depth_mm / 10.0, flutes=flutes, immersion=immersion)
    per_chip, edge = mean_force_vectors(config)
    for chip_mm, depth_mm in ((0.05, 1.0), (0.2, 2.5)):
        expected = tooth_period_mean(config, chip_mm, depth_mm)
        assert_allclose(depth_mm * (chip_mm * per_chip + edge), expected, rtol=2e-3, atol=0.05)


def test_a_slot_pushes_along_the_normal_with_the_tangential_coefficient() -> None:
    """Full immersion (a_e = D), no edge force: F̄_n = z a_p c K_tc / 4, F̄_f = −z a_p c K_rc / 4 (Altintas)."""
    config = MillingConfig(radial_engagement=1.0, tangential_edge_n_mm=0.0, radial_edge_n_mm=0.0, flutes=4)
    per_chip, edge = mean_force_vectors(config)
    assert_allclose(per_chip, [-4 * 168.0 / 4, 4 * 796.0 / 4], rtol=1e-12)
    assert_allclose(edge, [0.0, 0.0], atol=1e-12)


def test_steady_cutting_without_the_periodic_part_reaches_the_mean_and_scales_with_depth() -> None:
    config = MillingConfig(periodic_gain=0.0, flutes=4)
    process = MillingProcess(config, DepthSchedule([[0.0, 1.0], [0.5, 3.0]]))
    feed_m_s = 0.01                                                 # 600 mm/min
    forces = [process.step(feed_m_s, 0.001) for _ in range(1000)]
    chip_mm = config.feed_per_tooth_mm(feed_m_s)
    assert chip_mm == pytest.approx(600.0 / (1200.0 * 4))
    at_1, at_3 = (float(np.hypot(*process.mean_force(chip_mm, d))) for d in (1.0, 3.0))
    assert forces[499] == pytest.approx(at_1, rel=1e-9) and forces[-1] == pytest.approx(at_3, rel=1e-9)
    assert at_3 == pytest.approx(3.0 * at_1)
    assert forces[500] < at_3 * 0.5, "a depth step rises through the tooth-pass lag, not at once"


def test_the_periodic_part_beats_at_the_tooth_passing_frequency_with_the_mean_kept() -> None:
    config = MillingConfig(flutes=3, spindle_rpm=1000.0, radial_engagement=0.2)   # f_d = 50 Hz, one tooth at a time
    process = MillingProcess(config, DepthSchedule([[0.0, 2.0]]))
    dt_s = 1.0e-4
    force = np.array([process.step(0.01, dt_s) for _ in range(20000)])[5000:]      # 1.5 s after 0.5 s
    spectrum = np.abs(np.fft.rfft(force - force.mean()))
    frequencies = np.fft.rfftfreq(force.size, dt_s)
    assert frequencies[np.argmax(spectrum)] == pytest.approx(config.tooth_frequency_hz, abs=1.0)
    assert force.min() < 0.2 * force.max(), "at 2 mm radial depth and 3 flutes the teeth are often all out"
    assert config.tooth_frequency_hz == 50.0


def test_a_stopped_feed_cuts_nothing_and_reset_restarts() -> None:
    process = MillingProcess(MillingConfig(), DepthSchedule([[0.0, 2.0]]))
    assert process.step(0.0, 0.01) == 0.0
    assert process.step(0.01, 0.01) > 0.0
    process.reset()
    assert (process.t_s, process.measured_n) == (0.0, 0.0)
    with pytest.raises(FaultError, match="feed_speed_m_s must be finite, got nan"):
        process.step(float("nan"), 0.01)


@pytest.mark.parametrize(("changes", "message"), [
    ({"radial_engagement": 1.2}, "radial_engagement must be in"),
    ({"immersion": "side"}, "milling.immersion must be one of"),
    ({"flutes": 0}, "flutes"),
    ({"feed_axes": ["x", "x"]}, "milling.feed_axes must be 1 to 3 distinct axis names, got ['x', 'x']"),
    ({"feed_axes": "xy"}, "milling.feed_axes must be 1 to 3 distinct axis names"),
    ({"periodic_gain": 2.0}, "periodic_gain"),
    ({"tangential_n_mm2": -1.0}, "tangential_n_mm2"),
])
def test_a_bad_milling_config_is_refused_naming_the_option(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError) as err:
        CuttingConfig.from_mapping({**MILLING, "milling": changes})
    assert message in str(err.value)


def test_milling_is_a_registered_process_fed_by_the_feed_vector() -> None:
    assert {"turning", "milling"} <= set(CUTTING_PROCESSES)
    config = PlantConfig.from_mapping({"model": "paper000", "axes": ["x", "y"], "cutting": MILLING})
    plant = make_plant(config)
    drives = make_plant({"model": "paper000", "axes": ["x", "y"]})
    process = MillingProcess(config.cutting.milling, config.cutting.depth_schedule())
    plant.reset([0.0, 0.0])
    drives.reset([0.0, 0.0])
    forces, expected = [], []
    for k in range(100):
        commands = [40.0, 30.0 * math.cos(0.05 * k)]                          # DAC counts on both axes
        before = np.array(drives.state()[1], dtype=float)
        drives.step(commands, 0.001)
        plant.step(commands, 0.001)
        mean_m_s = 0.5 * (before + np.array(drives.state()[1], dtype=float))
        expected.append(process.step(float(np.hypot(*mean_m_s)), 0.001))
        forces.append(cutting_force_n(plant))
    assert forces == expected and max(forces) > 0.0
    assert plant.positions_m().tolist() == drives.positions_m().tolist(), "the process does not load the axes"
    assert plant.describe()["cutting"]["model"] == "milling"
    assert plant.describe()["cutting"]["depth_schedule"] == [[0.0, 1.0], [0.05, 2.0]]


def test_the_wrapper_refuses_feed_axes_the_plant_lacks() -> None:
    with pytest.raises(ConfigError, match=r"cutting.milling.feed_axes must be one of the plant's axes "
                                          r"\['x', 'z'\], got 'y'"):
        make_plant({"model": "paper003", "axes": ["x", "z"], "velocity_loop": {"spindle_rpm": 0},
                    "cutting": MILLING})


def test_the_section_round_trips_through_its_values() -> None:
    config = CuttingConfig.from_mapping(MILLING)
    assert CuttingConfig.from_mapping(config.values()) == config
    assert config.milling.feed_axes == ("x", "y") and config.milling.flutes == 4


def test_a_long_sample_is_cut_into_sub_steps_so_the_dynamometer_filters_the_teeth() -> None:
    """At T = 10 ms and f_d = 79.15 Hz: 7 sub-steps equal 7 short samples; one held sample per T aliases.

    (1187.25 rpm, not 1200: there a sample would fall exactly on a tooth's entry every 5 ticks, where the sum of
    the sub-steps and the product of the step differ in the last bit and decide whether the tooth cuts.)
    """
    base = {"flutes": 4, "spindle_rpm": 1187.25, "dynamometer_tau_s": 0.02}
    schedule = DepthSchedule([[0.0, 2.0]])
    coarse = MillingProcess(MillingConfig(**base), schedule)
    fine = MillingProcess(MillingConfig(**base, substeps_per_tooth=1), schedule)
    held = MillingProcess(MillingConfig(**base, substeps_per_tooth=1), schedule)
    sub_s = 0.01 / 7
    resolved, fine_samples, aliased = [], [], []
    for _ in range(200):
        resolved.append(coarse.step(0.02, 0.01))
        fine_samples.append([fine.step(0.02, sub_s) for _ in range(7)][-1])
        aliased.append(held.step(0.02, 0.01))
    assert_allclose(resolved, fine_samples, rtol=1e-9)
    steady = slice(100, None)
    assert np.ptp(resolved[steady]) < 0.5 * np.ptp(aliased[steady])
    assert np.mean(resolved[steady]) == pytest.approx(np.mean(aliased[steady]), rel=0.2)
