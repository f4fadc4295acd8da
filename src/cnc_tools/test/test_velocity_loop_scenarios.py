"""The velocity-loop scenarios (papers 002, 003) run in the engine and agree with their linear models."""
from __future__ import annotations

from pathlib import Path

import control as ct
import numpy as np
import pytest

from cnc_contour_control.core.units import M_PER_PULSE_PAPER002
from cnc_contour_control.core.velocity_models import PAPER002_MODELS, PiVelocityLoop
from cnc_contour_control.motion.accel_decel import filter_coefficients
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"


def _at(system: ct.TransferFunction, f_hz: float, dt_s: float) -> complex:
    return complex(system(np.exp(2j * np.pi * f_hz * dt_s)))


def test_paper003_circle_radius_reduction_is_the_linear_loops() -> None:
    """Steady radius reduction = R (1 − |k P/(1 + k P)| |F|) at ω = F/R: position loop, PI loop (ZOH), T_ip."""
    scenario = load_scenario(SCENARIOS / "paper003_circle.yaml")
    record = run_engine(scenario)
    dt_s, radius_m = scenario.sample_time_s, 0.01
    omega_hz = (4.0 / 60.0) / radius_m / (2.0 * np.pi)
    drawn = record.summary["plant"]["axes"]["x"]
    assert (drawn["kp"], drawn["ki"]) == (1.1396, 101.121)  # the paper's standard column
    loop = PiVelocityLoop(drawn["torque_per_inertia"], drawn["kp"], drawn["ki"])
    position = ct.sample_system(ct.tf(loop.lti().num, loop.lti().den) * ct.tf([1.0], [1.0, 0.0]), dt_s, "zoh")
    k = scenario.servos[0].law_params["kp"]
    b, a = filter_coefficients(scenario.interpolator.accel_decel, dt_s)
    accel_decel = ct.tf(b + [0.0] * (len(a) - len(b)), a, dt_s)
    gain = abs(_at(ct.feedback(k * position, 1), omega_hz, dt_s)) * abs(_at(accel_decel, omega_hz, dt_s))
    xy = record.joint_states.position_m
    t_s = record.joint_states.stamp_ns * 1e-9
    steady = (t_s > 0.5) & (t_s < 0.9)
    radius = np.hypot(xy[steady, 0], xy[steady, 1] - radius_m)
    assert radius_m - radius.mean() == pytest.approx(radius_m * (1.0 - gain), rel=1e-3)
    assert record.commands["x"].command_unit == "m/s"


@pytest.mark.parametrize("axis", ["x", "y"])
def test_paper002_circle_has_the_periodic_error_its_model_predicts(axis: str) -> None:
    """The f_d = 50 Hz line of the tracking error (lock-in, detrended) = |P_x/(1 + K_pp P_x)| A,
    P_x = P_n · trapezoid."""
    scenario = load_scenario(SCENARIOS / "paper002_circle.yaml").variant(duration_s=4.0)
    record = run_engine(scenario)
    k = ["x", "y"].index(axis)
    dt_s, f_d_hz, kpp = scenario.sample_time_s, 1500 * 2 / 60.0, scenario.servos[k].law_params["kp"]
    amplitude_m_s = scenario.plant.axis_overrides[axis]["disturbance_amplitude_mm_s"] * 1e-3
    model = PAPER002_MODELS[axis]
    position = ct.tf(list(model.numerator), list(model.denominator), dt_s) * ct.tf([dt_s / 2, dt_s / 2], [1, -1], dt_s)
    predicted_m = abs(_at(position / (1 + kpp * position), f_d_hz, dt_s)) * amplitude_m_s
    t_s = record.joint_states.stamp_ns * 1e-9
    window = (t_s >= 0.5) & (t_s < 3.5)  # x moves, y turns at 0 s: no reversal inside
    error = (record.reference.position_m - record.joint_states.position_m)[window, k]
    error = error - np.polyval(np.polyfit(t_s[window], error, 6), t_s[window])
    measured_m = abs(2.0 * np.mean(error * np.exp(-2j * np.pi * f_d_hz * t_s[window])))
    assert measured_m == pytest.approx(predicted_m, rel=0.02)  # the encoder's pulse costs < 1 %
    pulses = record.joint_states.position_m[:, k] / M_PER_PULSE_PAPER002
    assert np.max(np.abs(pulses - np.round(pulses))) < 1e-6
