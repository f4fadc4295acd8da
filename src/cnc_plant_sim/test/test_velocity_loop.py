"""The velocity-loop plants (papers 002, 003): loops against scipy.signal, disturbance, encoder, validation."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import signal

from cnc_contour_control.axis.spindle import SpindleSchedule
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.units import M_PER_PULSE_PAPER002
from cnc_contour_control.core.velocity_models import PAPER002_MODELS, PAPER003_TORQUE_PER_INERTIA, PiVelocityLoop
from cnc_plant_sim.models.plant import PLANTS, PlantConfig, make_plant
from cnc_plant_sim.models.velocity_loop import (
    PAPER003_STANDARD_GAINS,
    VelocityLoopOptions,
    VelocityLoopPlant,
    pi_loop_from_discrete,
)

DT_S = 0.001
NO_ENCODER = {"encoder_pulse_m": 0.0}


def _plant(model: str, overrides: dict | None = None, **options: object) -> VelocityLoopPlant:
    plant = make_plant({"model": model, "axes": ["x", "y"], "axis_overrides": overrides or {},
                        "velocity_loop": {**NO_ENCODER, **options}})
    assert isinstance(plant, VelocityLoopPlant)
    return plant


def _run(plant: VelocityLoopPlant, commands: np.ndarray, dt_s: float = DT_S) -> tuple[np.ndarray, np.ndarray]:
    """Velocities and true positions after each step, shape (N, n_axes)."""
    v, x = [], []
    for row in commands:
        plant.step(list(row), dt_s)
        v.append(plant.velocities_m_s())
        x.append(plant.true_positions_m())
    return np.array(v), np.array(x)


@pytest.mark.parametrize("substeps", [1, 4])
def test_pi_loop_step_matches_scipy_lti(substeps: int) -> None:
    plant = make_plant({"model": "paper003", "axes": ["x"], "substeps": substeps, "velocity_loop": NO_ENCODER})
    u_m_s = 0.01
    v, x = _run(plant, np.full((200, 1), u_m_s))
    t = DT_S * np.arange(201)  # scipy starts at T[0]: the sample after step k is row k + 1
    loop = PiVelocityLoop(PAPER003_TORQUE_PER_INERTIA, PAPER003_STANDARD_GAINS["kp"], PAPER003_STANDARD_GAINS["ki"])
    expected = signal.step(loop.lti(), T=t)[1][1:]
    assert_allclose(v[:, 0], u_m_s * expected, atol=1e-12 * u_m_s, rtol=1e-9)
    # the position is the exact integral of the velocity: the step response of P(s)/s
    num, den = loop.lti().num, np.polymul(loop.lti().den, [1.0, 0.0])
    ramp = signal.step(signal.lti(num, den), T=t)[1][1:]
    assert_allclose(x[:, 0], u_m_s * ramp, atol=1e-9 * u_m_s)


def test_paper003_axes_have_the_papers_loop() -> None:
    loop = PiVelocityLoop(PAPER003_TORQUE_PER_INERTIA, PAPER003_STANDARD_GAINS["kp"], PAPER003_STANDARD_GAINS["ki"])
    assert loop.damping() == pytest.approx(0.71, abs=0.01)  # the paper's standard column
    assert loop.natural_frequency_rad_s() == pytest.approx(126.0, abs=0.5)
    plant = _plant("paper003", {"y": {"kp": 2.596, "ki": 99.522}})  # per-axis override: the optimal column
    assert plant.describe()["axes"]["y"]["kp"] == 2.596 and plant.describe()["axes"]["x"]["kp"] == 1.1396


@pytest.mark.parametrize("axis", ["x", "y"])
def test_discrete_loop_matches_lfilter(axis: str) -> None:
    rng = np.random.default_rng(3)
    commands = rng.uniform(-0.01, 0.01, size=(300, 2))
    v, x = _run(_plant("paper002"), commands)
    k = ["x", "y"].index(axis)
    model = PAPER002_MODELS[axis]
    expected = signal.lfilter(model.numerator, model.denominator, np.append(commands[:, k], 0.0))[1:]
    assert_allclose(v[:, k], expected, rtol=1e-12, atol=1e-18)
    trapezoid = np.cumsum(0.5 * DT_S * (np.append(0.0, expected[:-1]) + expected))
    assert_allclose(x[:, k], trapezoid, atol=1e-15)


@pytest.mark.parametrize("axis", ["x", "y"])
def test_continuous_form_of_paper002_follows_the_identified_step(axis: str) -> None:
    fitted = pi_loop_from_discrete(PAPER002_MODELS[axis])
    continuous = signal.step(fitted.lti(), T=DT_S * np.arange(301))[1][1:]
    _, (discrete,) = signal.dstep(PAPER002_MODELS[axis].dlti(), n=301)
    assert np.max(np.abs(continuous - discrete.ravel()[1:])) < 0.01  # a few per mille of the unit step
    plant = _plant("paper002", {axis: {"loop": "pi"}})
    v, _ = _run(plant, np.full((300, 2), 1.0))
    assert_allclose(v[:, ["x", "y"].index(axis)], continuous, atol=1e-9)


def test_discrete_loop_refuses_another_sample_time() -> None:
    plant = _plant("paper002")
    with pytest.raises(ConfigError, match=r"axis x: discrete_model 'x' holds only at its sample time 0.001 s, "
                                          r"got sample_time_s 0.002"):
        plant.step([0.0, 0.0], 0.002)


@pytest.mark.parametrize("rpm, flutes, f_hz", [(1500, 2, 50.0), (3000, 4, 200.0), (600, 1, 10.0)])
def test_disturbance_frequency_from_rpm_and_flutes(rpm: float, flutes: int, f_hz: float) -> None:
    amplitude_mm_s = 0.2
    plant = _plant("paper002", {"x": {"disturbance_amplitude_mm_s": amplitude_mm_s}}, spindle_rpm=rpm, flutes=flutes)
    n = 1000
    d = []
    for _ in range(n):
        plant.step([0.001, 0.001], DT_S)  # moving: no stiction
        d.append(plant.disturbances_m_s()[0])
    spectrum = np.abs(np.fft.rfft(d)) * 2.0 / n
    freqs = np.fft.rfftfreq(n, DT_S)
    assert freqs[np.argmax(spectrum)] == pytest.approx(f_hz)
    assert spectrum.max() == pytest.approx(amplitude_mm_s * 1e-3, rel=1e-6)


def test_spindle_schedule_changes_frequency_with_continuous_phase() -> None:
    options = VelocityLoopOptions(spindle_rpm=1500, flutes=2, spindle_schedule_t_s=(0.5,), spindle_schedule_rpm=(1650,))
    schedule = options.schedule()
    assert schedule.frequency_hz(0.49) == 50.0 and schedule.frequency_hz(0.5) == pytest.approx(55.0)
    assert schedule.phase_rad(0.5) == pytest.approx(2 * math.pi * 50 * 0.5)
    assert schedule.phase_rad(0.6) == pytest.approx(2 * math.pi * (50 * 0.5 + 55 * 0.1))
    eps = 1e-9
    jump_rad = schedule.phase_rad(0.5 + eps) - schedule.phase_rad(0.5 - eps)
    assert jump_rad == pytest.approx(2 * math.pi * 105e-9, rel=1e-6)


def test_spindle_schedule_in_the_plant_is_the_same_every_build() -> None:
    def disturbances() -> list[float]:
        plant = _plant("paper002", {"x": {"disturbance_amplitude_mm_s": 0.1}},
                       spindle_schedule_t_s=[0.05], spindle_schedule_rpm=[3000])
        out = []
        for _ in range(100):
            plant.step([0.001, 0.001], DT_S)
            out.append(plant.disturbances_m_s()[0])
        return out

    first = disturbances()
    assert first == disturbances()
    expected = [1e-4 * math.sin(SpindleSchedule((0.0, 0.05), (50.0, 100.0)).phase_rad(k * DT_S)) for k in range(100)]
    assert_allclose(first, expected, atol=1e-15)


def test_stiction_holds_an_axis_below_breakaway_and_coulomb_opposes_motion() -> None:
    plant = _plant("paper003", {"x": {"coulomb_mm_s": 0.5, "stiction_mm_s": 1.0}})
    v, _ = _run(plant, np.tile([[0.9e-3, 0.9e-3]], (100, 1)))
    assert np.all(v[:, 0] == 0.0) and v[-1, 1] > 0.8e-3  # x sticks below 1 mm/s, y has no friction
    v, _ = _run(plant, np.tile([[2e-3, 2e-3]], (500, 1)))
    assert v[-1, 0] == pytest.approx(1.5e-3, rel=1e-3)  # moving: the loop settles at u - F_c


def test_encoder_rounds_positions_to_pulses() -> None:
    plant = make_plant({"model": "paper002", "axes": ["x", "y"]})  # the default encoder: paper 002's pulse
    for _ in range(37):
        plant.step([0.0013, -0.0007], DT_S)
    positions, _ = plant.state()
    true = plant.true_positions_m()
    for measured, exact in zip(positions, true):
        assert measured / M_PER_PULSE_PAPER002 == pytest.approx(round(measured / M_PER_PULSE_PAPER002), abs=1e-6)
        assert abs(measured - exact) <= 0.5 * M_PER_PULSE_PAPER002
    assert_allclose(plant.positions_m(), positions)


def test_fault_leaves_every_axis_where_it_was() -> None:
    plant = _plant("paper002")
    plant.step([0.001, 0.001], DT_S)
    before = (plant.true_positions_m(), plant.velocities_m_s().tolist())
    with pytest.raises(FaultError, match="axis y: command must be finite"):
        plant.step([0.001, math.nan], DT_S)
    assert (plant.true_positions_m(), plant.velocities_m_s().tolist()) == before


@pytest.mark.parametrize("options, message", [
    ({"spindle_rpm": 15000, "flutes": 2}, r"velocity_loop.spindle_rpm: f_d = rpm \* flutes / 60 must be < 500.0 Hz "
                                          r"\(Nyquist at sample_time_s 0.001\), got 500.0 Hz"),
    ({"spindle_schedule_t_s": [1.0], "spindle_schedule_rpm": [20000]}, r"must be < 500.0 Hz .* got 666.6"),
])
def test_disturbance_at_or_above_nyquist_is_refused(options: dict, message: str) -> None:
    plant = _plant("paper002", **options)
    with pytest.raises(ConfigError, match=message):
        plant.step([0.0, 0.0], DT_S)


@pytest.mark.parametrize("section, message", [
    ({"velocity_loop": {"flutes": 0}}, r"velocity_loop.flutes must be in \[1, 1000\], got 0"),
    ({"velocity_loop": {"spindle_rpm": -1}}, r"velocity_loop.spindle_rpm must be in \[0.0, 1000000.0\], got -1"),
    ({"velocity_loop": {"spindle_schedule_t_s": [1.0, 0.5], "spindle_schedule_rpm": [1, 2]}},
     r"velocity_loop.spindle_schedule_t_s\[1\] must be > 1, got 0.5"),
    ({"velocity_loop": {"spindle_schedule_t_s": [1.0], "spindle_schedule_rpm": []}},
     r"spindle_schedule_rpm must have one entry per spindle_schedule_t_s \(1\), got 0"),
    ({"axis_overrides": {"x": {"loop": "pid"}}}, r"axis_overrides.x.*loop.*pid"),
    ({"axis_overrides": {"x": {"coulomb_mm_s": 2.0, "stiction_mm_s": 1.0}}},
     r"axis_overrides.x.stiction_mm_s must be >= coulomb_mm_s \(2.0\), got 1.0"),
    ({"axis_overrides": {"y": {"kp": -1}}}, r"axis_overrides.y.kp must be in \[0.0, 1000000000.0\], got -1"),
    ({"axis_overrides": {"x": {"discrete_model": "z"}}}, r"axis_overrides.x.*discrete_model.*'z'"),
])
def test_bad_config_is_refused_naming_the_key(section: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        PlantConfig.from_mapping({"model": "paper002", "axes": ["x", "y"], **section})


def test_registry_entries() -> None:
    assert PLANTS["paper002"].axis_config is PLANTS["paper003"].axis_config
    plant = _plant("paper002")
    assert plant.command_unit == "m/s" and plant.forces_n() is None
    assert [c.loop for c in plant.axis_configs] == ["discrete", "discrete"]
    assert plant.describe()["axes"]["y"]["discrete_model"] == "y"
